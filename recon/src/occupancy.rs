//! The SDF on a coarse grid over the unit sphere's cube, refreshed from the field every few
//! iterations: where it shows the surface to be far, a training step's ray sampling reads the
//! SDF from it instead of evaluating the networks (the role of the occupancy grids of
//! instant-NGP, NeuS2 and instant-nsr-pl, which keep samples out of empty space).

use crate::model::Model;
use rayon::prelude::*;

/// Cells per axis over `[-1, 1]^3`.
pub const CELLS: usize = 32;

/// Iterations between refreshes.
pub const REFRESH_EVERY: u32 = 16;

/// How far from the surface, in cell diagonals, every corner of a cell must be for the grid to
/// stand in for the field inside it: one diagonal is where a surface could enter the cell of a
/// distance field; the rest covers a field that is not yet one and the iterations since the
/// refresh.
const FAR_DIAGONALS: f32 = 2.0;

/// The SDF at the corners of [`CELLS`]^3 cells over `[-1, 1]^3`.
#[derive(Clone, Debug, PartialEq)]
pub struct OccupancyGrid {
    /// `(CELLS + 1)^3` corner values, x fastest.
    sdf: Vec<f32>,
}

/// Corners per axis.
const SIDE: usize = CELLS + 1;

/// A cell's side.
const CELL: f32 = 2.0 / CELLS as f32;

impl OccupancyGrid {
    /// Values a grid holds.
    pub const VALUES: usize = SIDE * SIDE * SIDE;

    /// The grid of `model`'s SDF at `params`, its hash grid's levels weighted by `level_weight`.
    pub fn new(model: &Model, params: &[f32], level_weight: &[f32]) -> Self {
        Self::from_sdf(|points| model.field.sdf(params, points, level_weight))
    }

    /// The grid of the SDF `sdf` gives at points (n x 3), one plane of corners at a time.
    fn from_sdf(sdf: impl Fn(&[f32]) -> Vec<f32> + Sync) -> Self {
        let sdf = (0..SIDE)
            .into_par_iter()
            .flat_map_iter(|z| {
                let points: Vec<f32> =
                    (0..SIDE * SIDE).flat_map(|k| [k % SIDE, k / SIDE, z].map(|i| i as f32 * CELL - 1.0)).collect();
                sdf(&points)
            })
            .collect();
        Self { sdf }
    }

    /// The grid's values, `(CELLS + 1)^3` SDF values at the cells' corners, x fastest.
    pub fn values(&self) -> &[f32] {
        &self.sdf
    }

    /// The grid of [`OccupancyGrid::values`] (None unless there are [`OccupancyGrid::VALUES`]).
    pub fn from_values(values: &[f32]) -> Option<Self> {
        (values.len() == Self::VALUES).then(|| Self { sdf: values.to_vec() })
    }

    /// The SDF at `p` interpolated from the grid, where every corner of `p`'s cell lies
    /// farther from the surface than `FAR_DIAGONALS` cell diagonals (the surface cannot be
    /// near `p`); `None` where it may be.
    pub fn far_sdf(&self, p: [f32; 3]) -> Option<f32> {
        let far = FAR_DIAGONALS * CELL * 3f32.sqrt();
        let mut cell = [0usize; 3];
        let mut frac = [0f32; 3];
        for a in 0..3 {
            let x = ((p[a] + 1.0) / CELL).clamp(0.0, CELLS as f32);
            cell[a] = (x as usize).min(CELLS - 1);
            frac[a] = x - cell[a] as f32;
        }
        let mut value = 0.0;
        for k in 0..8 {
            let bit = [k & 1, (k >> 1) & 1, (k >> 2) & 1];
            let corner = self.sdf[(cell[0] + bit[0]) + SIDE * ((cell[1] + bit[1]) + SIDE * (cell[2] + bit[2]))];
            if corner.abs() <= far {
                return None;
            }
            let w: f32 = (0..3).map(|a| if bit[a] == 1 { frac[a] } else { 1.0 - frac[a] }).product();
            value += w * corner;
        }
        Some(value)
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use rmvp_dataset::rng::Rng;

    /// A sphere of radius 0.5 and a plate 0.004 thick (a sixteenth of a cell) across it, at
    /// `z = 0.3` and out to 0.8 from the axis.
    pub(crate) fn sphere_and_plate(p: &[f32]) -> f32 {
        let sphere = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - 0.5;
        let plate = ((p[2] - 0.3).abs() - 0.002).max(p[0].abs().max(p[1].abs()) - 0.8);
        sphere.min(plate)
    }

    #[test]
    fn the_grid_stands_in_only_where_the_surface_is_far_however_thin() {
        let grid = OccupancyGrid::from_sdf(|points| points.chunks_exact(3).map(sphere_and_plate).collect());
        let mut rng = Rng::for_pixel(3, 0, 0);
        let (mut stood_in, mut near) = (0, 0);
        for _ in 0..200_000 {
            let p = [0, 1, 2].map(|_| 2.0 * rng.next_f32() - 1.0);
            let truth = sphere_and_plate(&p);
            match grid.far_sdf(p) {
                Some(value) => {
                    stood_in += 1;
                    // Never within a cell of the surface (the sample spacing of a ray is about
                    // as much), and on the surface's side.
                    assert!(truth.abs() > CELL, "{p:?}: the surface is {truth} away");
                    assert_eq!(value > 0.0, truth > 0.0, "{p:?}: {value} against {truth}");
                }
                None => near += usize::from(truth.abs() > 0.5),
            }
        }
        println!("the grid stands in at {stood_in} of 200000 points");
        assert!(stood_in > 100_000 && near == 0, "stood in at {stood_in}; {near} points half a unit away not");
    }
}
