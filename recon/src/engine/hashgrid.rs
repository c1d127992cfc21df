//! Multiresolution hash encoding (Müller et al. 2022) of points in `[-1, 1]^3`, trilinear, with
//! per-level weights for coarse-to-fine annealing (Neuralangelo).

use super::params::{Group, ParamLayout};
use rayon::prelude::*;
use rmvp_dataset::rng::Rng;
use std::ops::Range;

/// Features per level.
pub const FEATURES: usize = 2;

/// A hash-grid encoding's shape and where its tables live.
#[derive(Clone, Debug)]
pub struct HashGrid {
    levels: usize,
    table: usize,
    resolutions: Vec<u32>,
    offset: usize,
}

/// The eight corners of a point's cell at one level: their entries' positions in the level's
/// table and their trilinear weights.
#[derive(Clone, Copy)]
struct Corners {
    index: [usize; 8],
    weight: [f32; 8],
}

/// Points whose corners the encoding finds, and asks memory for, before it reads any of them.
const BLOCK: usize = 32;

/// Ask for the cache line of `table[at]` ahead of its read (a hint: nothing happens elsewhere
/// than on x86-64, and an index past the table is never read).
#[inline(always)]
fn prefetch(table: &[f32], at: usize) {
    #[cfg(target_arch = "x86_64")]
    if let Some(entry) = table.get(at) {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        // SAFETY: a prefetch never faults; its address is an element of `table`.
        unsafe { _mm_prefetch::<_MM_HINT_T0>(std::ptr::from_ref(entry).cast()) }
    }
}

impl HashGrid {
    /// `levels` levels from `base` to `finest` cells per axis, `2^log2_table` entries per level.
    pub fn new(layout: &mut ParamLayout, levels: usize, log2_table: u32, base: u32, finest: u32) -> Self {
        let growth = if levels > 1 { (finest as f64 / base as f64).powf(1.0 / (levels - 1) as f64) } else { 1.0 };
        let resolutions: Vec<u32> = (0..levels).map(|l| (base as f64 * growth.powi(l as i32)).round() as u32).collect();
        let table = 1usize << log2_table;
        // One range per level, contiguous: Adam can give each level its own rate. A level whose
        // corners fit its table uses only their entries.
        let offset = layout.len();
        for (level, &res) in resolutions.iter().enumerate() {
            let used = (res as usize + 1).pow(3).min(table);
            layout.reserve(used * FEATURES, Group::Grid { level });
            if used < table {
                layout.reserve((table - used) * FEATURES, Group::Unused);
            }
        }
        Self { levels, table, resolutions, offset }
    }

    /// Number of output features (`levels * 2`).
    pub fn outputs(&self) -> usize {
        self.levels * FEATURES
    }

    /// Number of levels.
    pub fn levels(&self) -> usize {
        self.levels
    }

    /// Entries per level's table (a power of two).
    pub fn table_entries(&self) -> usize {
        self.table
    }

    /// Where the first level's table starts in the parameter vector (levels follow each other).
    pub fn offset(&self) -> usize {
        self.offset
    }

    /// Cells per axis of each level.
    pub fn resolutions(&self) -> &[u32] {
        &self.resolutions
    }

    /// Uniform `[-1e-4, 1e-4]` features, as instant-NGP.
    pub fn init(&self, params: &mut [f32], rng: &mut Rng) {
        let n = self.levels * self.table * FEATURES;
        params[self.offset..self.offset + n].iter_mut().for_each(|v| *v = (rng.next_f32() * 2.0 - 1.0) * 1e-4);
    }

    /// Where level `level`'s table lies in the parameter vector.
    fn table_range(&self, level: usize) -> Range<usize> {
        let start = self.offset + level * self.table * FEATURES;
        start..start + self.table * FEATURES
    }

    /// The eight corners of `p`'s cell at `level`: their entries' positions in the level's
    /// table, and their trilinear weights. Inlined into the encoding's and the scatter's loops.
    #[inline(always)]
    fn corners(&self, level: usize, p: [f32; 3]) -> Corners {
        let res = self.resolutions[level];
        let side = res as usize + 1;
        let dense = side * side * side <= self.table;
        let mut cell = [0u32; 3];
        let mut frac = [0f32; 3];
        for a in 0..3 {
            let x = ((p[a] + 1.0) * 0.5).clamp(0.0, 1.0) * res as f32;
            let c = (x as u32).min(res - 1); // x >= 0: truncation is floor
            cell[a] = c;
            frac[a] = x - c as f32;
        }
        let mut out = Corners { index: [0; 8], weight: [0.0; 8] };
        for k in 0..8 {
            let bit = [k & 1, (k >> 1) & 1, (k >> 2) & 1];
            let mut w = 1.0;
            let mut c = [0usize; 3];
            for a in 0..3 {
                c[a] = (cell[a] as usize) + bit[a];
                w *= if bit[a] == 1 { frac[a] } else { 1.0 - frac[a] };
            }
            let slot = if dense {
                c[0] + side * (c[1] + side * c[2])
            } else {
                let h =
                    (c[0] as u32) ^ (c[1] as u32).wrapping_mul(2_654_435_761) ^ (c[2] as u32).wrapping_mul(805_459_861);
                h as usize & (self.table - 1)
            };
            out.index[k] = slot * FEATURES;
            out.weight[k] = w;
        }
        out
    }

    /// The corners at `level` of up to [`BLOCK`] `points` (3 each) into `block`, every entry
    /// asked of memory (in the level's `table`) before any is read: the entries of many points
    /// are on their way at once.
    #[inline(always)]
    fn block_corners(&self, level: usize, points: &[f32], table: &[f32], block: &mut [Corners; BLOCK]) {
        for (p, c) in points.chunks_exact(3).zip(block.iter_mut()) {
            *c = self.corners(level, [p[0], p[1], p[2]]);
            c.index.iter().for_each(|&at| prefetch(table, at));
        }
    }

    /// Encode `points` (n x 3) into `out` (n x outputs); level `l` is scaled by `level_weight[l]`.
    /// Level by level, so that one level's table stays in cache.
    pub fn encode(&self, params: &[f32], points: &[f32], level_weight: &[f32], out: &mut [f32]) {
        let width = self.outputs();
        let mut block = [Corners { index: [0; 8], weight: [0.0; 8] }; BLOCK];
        for (level, &lw) in level_weight.iter().enumerate().take(self.levels) {
            let table = &params[self.table_range(level)];
            for (points, out) in points.chunks(3 * BLOCK).zip(out.chunks_mut(width * BLOCK)) {
                if lw == 0.0 {
                    out.chunks_exact_mut(width).for_each(|o| o[level * FEATURES..(level + 1) * FEATURES].fill(0.0));
                    continue;
                }
                self.block_corners(level, points, table, &mut block);
                for (o, corners) in out.chunks_exact_mut(width).zip(&block) {
                    let mut f = [0f32; FEATURES];
                    for k in 0..8 {
                        let entry = &table[corners.index[k]..corners.index[k] + FEATURES];
                        for j in 0..FEATURES {
                            f[j] += corners.weight[k] * entry[j];
                        }
                    }
                    for j in 0..FEATURES {
                        o[level * FEATURES + j] = f[j] * lw;
                    }
                }
            }
        }
    }

    /// Write the table gradients of `d_out` (n x outputs) at `points` over `grad`'s tables.
    pub fn backward(&self, points: &[f32], level_weight: &[f32], d_out: &[f32], grad: &mut [f32]) {
        self.backward_batches(&[(points, d_out)], level_weight, grad);
    }

    /// Write the table gradients of several batches' `(points, d_out)` over `grad`'s tables:
    /// the levels in parallel, each level's table cleared and its batches scattered in order
    /// while it is in cache (the same sums whatever the number of threads).
    pub fn backward_batches(&self, batches: &[(&[f32], &[f32])], level_weight: &[f32], grad: &mut [f32]) {
        let width = self.outputs();
        let tables = &mut grad[self.offset..self.offset + self.levels * self.table * FEATURES];
        tables.par_chunks_mut(self.table * FEATURES).enumerate().for_each(|(level, table)| {
            table.fill(0.0);
            let lw = level_weight.get(level).copied().unwrap_or(0.0);
            if lw == 0.0 {
                return;
            }
            let mut block = [Corners { index: [0; 8], weight: [0.0; 8] }; BLOCK];
            for (points, d_out) in batches {
                for (points, d_out) in points.chunks(3 * BLOCK).zip(d_out.chunks(width * BLOCK)) {
                    self.block_corners(level, points, table, &mut block);
                    for (d, corners) in d_out.chunks_exact(width).zip(&block) {
                        let d = &d[level * FEATURES..(level + 1) * FEATURES];
                        for k in 0..8 {
                            let entry = &mut table[corners.index[k]..corners.index[k] + FEATURES];
                            for j in 0..FEATURES {
                                entry[j] += corners.weight[k] * lw * d[j];
                            }
                        }
                    }
                }
            }
        });
    }
}
