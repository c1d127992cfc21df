//! Where the normal error lies: each compared pixel's error ([`normal_errors`]) binned by three
//! things that may cause it, so that two reconstructions of a scene can be told apart by more
//! than their means:
//! - the input's degree of polarization at the pixel (training views with Stokes images): the
//!   AoP that the geometric cue reads is only as good as the DoP behind it;
//! - the true surface's GGX roughness there (a ground-truth mesh with a `roughness_0` or
//!   `roughness` vertex property): a rough lobe polarizes about its lit half vectors, not the
//!   normal;
//! - the depth complexity of the pixel's ray: how many times it crosses the true surface (two
//!   for a ray through a convex body; four or more behind folds, thin parts and concavities).
//!
//! [`normal_errors`]: crate::normals::normal_errors

use crate::normals::ViewNormalError;
use crate::Result;
use rayon::prelude::*;
use rmvp_dataset::{Mesh, Scene};
use rmvp_render::math::Vec3;
use rmvp_render::object::roughness_property;
use rmvp_render::Object;
use serde::{Deserialize, Serialize};

/// Edges of the DoP bins (those of `bench/aop_residuals.py`).
pub const DOP_EDGES: [f64; 7] = [0.0, 0.01, 0.02, 0.05, 0.1, 0.2, 1.0];
/// Edges of the roughness (GGX alpha) bins.
pub const ROUGHNESS_EDGES: [f64; 7] = [0.0, 0.05, 0.1, 0.15, 0.2, 0.3, 1.0];
/// Edges of the depth-complexity bins, in crossings of the true surface: 1-2, 3-4, 5 or more.
pub const CROSSING_EDGES: [f64; 4] = [1.0, 3.0, 5.0, MAX_CROSSINGS as f64 + 1.0];
/// Crossings counted along one ray at most.
const MAX_CROSSINGS: u32 = 64;

/// The pixels whose value lies in `[from, to)` (the last bin includes `to`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ErrorBin {
    /// Lower edge.
    pub from: f64,
    /// Upper edge.
    pub to: f64,
    /// Pixels compared in the bin.
    pub pixels: usize,
    /// Their mean normal error, degrees (`null` in JSON for an empty bin).
    pub mae_deg: Option<f64>,
}

/// The normal error binned by DoP, roughness and depth complexity.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ErrorBreakdown {
    /// By the input's DoP (of the channel-mean Stokes vector), over the views with Stokes
    /// images; empty when no view has them.
    pub by_dop: Vec<ErrorBin>,
    /// By the true surface's roughness at the pixel; empty when the ground-truth mesh has none.
    pub by_roughness: Vec<ErrorBin>,
    /// By the number of times the pixel's ray crosses the true surface.
    pub by_crossings: Vec<ErrorBin>,
}

impl ErrorBreakdown {
    /// One line per non-empty breakdown for people: each bin's range, mean error in degrees and
    /// share of the pixels (`by input DoP      0-0.01: 12.31 deg (23.0 %), ...`).
    pub fn lines(&self) -> Vec<String> {
        let range = |b: &ErrorBin| format!("{}-{}", b.from, b.to);
        // Crossings are counts: `[1, 3)` reads 1-2, the last bin "5 or more".
        let count = |b: &ErrorBin| match b.to > CROSSING_EDGES[2] {
            true => format!("{}+", b.from),
            false => format!("{}-{}", b.from, b.to - 1.0),
        };
        [
            line("by input DoP", &self.by_dop, range),
            line("by roughness", &self.by_roughness, range),
            line("by ray crossings", &self.by_crossings, count),
        ]
        .into_iter()
        .flatten()
        .collect()
    }
}

/// `what` and each non-empty bin of `bins` (named by `label`) with its mean error and share of
/// the pixels; `None` for no bins.
fn line(what: &str, bins: &[ErrorBin], label: impl Fn(&ErrorBin) -> String) -> Option<String> {
    let total = bins.iter().map(|b| b.pixels).sum::<usize>().max(1) as f64;
    let cells: Vec<String> = bins
        .iter()
        .filter_map(|b| {
            let mae = b.mae_deg?;
            Some(format!("{}: {mae:.2} deg ({:.1} %)", label(b), 100.0 * b.pixels as f64 / total))
        })
        .collect();
    (!bins.is_empty()).then(|| format!("{what:<17} {}", cells.join(", ")))
}

/// Sums of one breakdown's bins while pixels are added.
struct Accumulator {
    edges: &'static [f64],
    sums: Vec<(usize, f64)>,
}

impl Accumulator {
    fn new(edges: &'static [f64]) -> Self {
        Self { edges, sums: vec![(0, 0.0); edges.len() - 1] }
    }

    /// Add a pixel of `error` degrees whose value is `at` (outside the edges: not counted).
    fn add(&mut self, at: f64, error: f64) {
        let last = self.sums.len() - 1;
        let bin = self.edges.windows(2).position(|e| at >= e[0] && at < e[1]);
        let bin = bin.or_else(|| (at == self.edges[last + 1]).then_some(last));
        if let Some(b) = bin {
            self.sums[b].0 += 1;
            self.sums[b].1 += error;
        }
    }

    fn merge(mut self, other: Accumulator) -> Self {
        for (a, b) in self.sums.iter_mut().zip(other.sums) {
            a.0 += b.0;
            a.1 += b.1;
        }
        self
    }

    fn bins(&self) -> Vec<ErrorBin> {
        self.edges
            .windows(2)
            .zip(&self.sums)
            .map(|(e, &(pixels, sum))| ErrorBin {
                from: e[0],
                to: e[1],
                pixels,
                mae_deg: (pixels > 0).then(|| sum / pixels as f64),
            })
            .collect()
    }

    fn is_empty(&self) -> bool {
        self.sums.iter().all(|s| s.0 == 0)
    }
}

/// Bin the error maps of `views` (from [`crate::normals::normal_errors`] on `scene`) by the
/// input's DoP, the true roughness and the depth complexity of `gt`, the ground-truth mesh in
/// the scene's world frame.
pub fn error_breakdown(views: &[ViewNormalError], scene: &Scene, gt: &Mesh) -> Result<ErrorBreakdown> {
    let has_roughness = roughness_property(gt).is_some();
    let truth = Object::geometry(gt)?;
    let empty = || [&DOP_EDGES[..], &ROUGHNESS_EDGES, &CROSSING_EDGES].map(Accumulator::new);
    let [dop, roughness, crossings] = views
        .par_iter()
        .filter_map(|v| scene.views.iter().find(|s| s.name == v.view).map(|s| (v, s)))
        .map(|(errors, view)| {
            let mut acc = empty();
            let input_dop = view.stokes.as_ref().map(|s| s.aop_dop().1);
            let (w, _) = errors.error_map.size();
            let origin = Vec3::from_f64(&view.camera.center().coords);
            for (k, &error) in errors.error_map.data().iter().enumerate() {
                if error.is_nan() {
                    continue;
                }
                let error = error as f64;
                if let Some(d) = &input_dop {
                    acc[0].add(d.data()[k] as f64, error);
                }
                let ray = view.camera.pixel_ray((k % w) as u32, (k / w) as u32);
                let direction = Vec3::from_f64(&ray.direction);
                let Some(first) = truth.intersect(origin, direction) else { continue };
                if has_roughness {
                    acc[1].add(first.surface.alpha as f64, error);
                }
                acc[2].add(crossings_after(&truth, origin, direction, first.p) as f64, error);
            }
            acc
        })
        .reduce(empty, |a, b| {
            let [a0, a1, a2] = a;
            let [b0, b1, b2] = b;
            [a0.merge(b0), a1.merge(b1), a2.merge(b2)]
        });
    let listed = |acc: &Accumulator| if acc.is_empty() { Vec::new() } else { acc.bins() };
    Ok(ErrorBreakdown { by_dop: listed(&dop), by_roughness: listed(&roughness), by_crossings: listed(&crossings) })
}

/// How many times the ray from `origin` along the unit `direction` crosses `object`'s surface,
/// its first crossing at `first` included (at most [`MAX_CROSSINGS`]).
fn crossings_after(object: &Object, origin: Vec3, direction: Vec3, first: Vec3) -> u32 {
    let mut count = 1;
    let mut hit = first;
    while count < MAX_CROSSINGS {
        // Past the hit by a relative step, so the same triangle is not found again.
        let travelled = (hit - origin).length();
        let Some(next) = object.intersect(hit + direction * (1e-4 * travelled).max(1e-6), direction) else { break };
        count += 1;
        hit = next.p;
    }
    count
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pixels_fall_in_the_bin_of_their_value() {
        let mut acc = Accumulator::new(&DOP_EDGES);
        acc.add(0.0, 10.0);
        acc.add(0.005, 20.0);
        acc.add(0.15, 4.0);
        acc.add(1.0, 2.0); // the upper edge of the last bin
        acc.add(1.5, 100.0); // outside every bin
        let bins = acc.bins();
        assert_eq!(bins.len(), 6);
        assert_eq!((bins[0].pixels, bins[0].mae_deg), (2, Some(15.0)));
        assert_eq!((bins[4].pixels, bins[4].mae_deg), (1, Some(4.0)));
        assert_eq!((bins[5].pixels, bins[5].mae_deg), (1, Some(2.0)));
        assert_eq!((bins[1].pixels, bins[1].mae_deg), (0, None));
    }

    #[test]
    fn lines_name_each_bin_and_its_share() {
        let mut crossings = Accumulator::new(&CROSSING_EDGES);
        crossings.add(2.0, 1.0);
        crossings.add(2.0, 3.0);
        crossings.add(4.0, 5.0);
        crossings.add(8.0, 8.0);
        let breakdown = ErrorBreakdown { by_dop: Vec::new(), by_roughness: Vec::new(), by_crossings: crossings.bins() };
        assert_eq!(
            breakdown.lines(),
            ["by ray crossings  1-2: 2.00 deg (50.0 %), 3-4: 5.00 deg (25.0 %), 5+: 8.00 deg (25.0 %)"]
        );
    }
}
