//! The small dense layers' matrix products without packing: `C += A B`, where every row of `B`
//! and `C` is a whole number of 16-float panels and each element of `A` is broadcast against a
//! row of `B`. A tile of `C` (a few rows, up to 64 columns) stays in vector registers while the
//! product runs down its depth, so the activations of the 64-wide layers of the fast networks
//! are never copied (matrixmultiply packs both operands of every product: nearly two fifths of
//! its time in a fast training step).
//!
//! Compiled for AVX-512 and for AVX2 with FMA, chosen at run time ([`Isa::detect`]); elsewhere
//! the networks keep matrixmultiply. Each element of `C` is summed over the depth in ascending
//! order by fused multiply-adds whatever the tile, so both instruction sets give the same bits.

/// Floats in one panel: a row of `B` and `C` is this many floats at a time (one AVX-512
/// register, two AVX2 registers).
pub const LANES: usize = 16;

/// `width` rounded up to whole panels.
pub fn padded(width: usize) -> usize {
    width.div_ceil(LANES) * LANES
}

/// The vector instructions the panel products are compiled for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Isa {
    /// AVX-512F: tiles of 4 rows by 64 columns (16 of the 32 registers).
    Avx512,
    /// AVX2 with FMA: tiles of 2 rows by 32 columns (8 of the 16 registers).
    Avx2,
}

impl Isa {
    /// The widest this processor has, or None where neither runs (the caller keeps SGEMM).
    pub fn detect() -> Option<Isa> {
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx512f") && std::arch::is_x86_feature_detected!("fma") {
                return Some(Isa::Avx512);
            }
            if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
                return Some(Isa::Avx2);
            }
        }
        None
    }

    /// Whether this processor runs `self` (for tests that compare the instruction sets).
    pub fn available(self) -> bool {
        match (self, Isa::detect()) {
            (_, None) => false,
            (Isa::Avx512, Some(best)) => best == Isa::Avx512,
            (Isa::Avx2, Some(_)) => true,
        }
    }
}

/// A matrix read element by element: `A(i, p) = data[i * row + p * column]`.
#[derive(Clone, Copy)]
pub struct Strided<'a> {
    /// The elements.
    pub data: &'a [f32],
    /// Step between rows `i`.
    pub row: usize,
    /// Step between columns `p`.
    pub column: usize,
}

/// A matrix of whole panels: row `p` is `data[p * stride..][..width]`, `width` a multiple of
/// [`LANES`] no greater than `stride`.
pub struct Panels<S> {
    /// The elements.
    pub data: S,
    /// Floats from one row to the next.
    pub stride: usize,
    /// Floats used in a row.
    pub width: usize,
}

/// What a product's sums start from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Start {
    /// `c += a b`: from what `c` holds.
    Add,
    /// `c = a b`: from zero; what `c` held is never read.
    Overwrite,
}

/// `c[i, :] (+)= sum over p < depth of a(i, p) b[p, :]` for the `rows` rows of `c`, on `isa`.
///
/// # Panics
/// If `isa` does not run here, the widths are not whole panels, or an operand is too short.
pub fn product(
    isa: Isa,
    start: Start,
    rows: usize,
    depth: usize,
    a: Strided,
    b: Panels<&[f32]>,
    c: Panels<&mut [f32]>,
) {
    assert!(isa.available(), "{isa:?} does not run on this processor");
    assert!(b.width == c.width && c.width.is_multiple_of(LANES) && c.width <= c.stride && b.width <= b.stride);
    if rows == 0 || c.width == 0 {
        return;
    }
    assert!(c.data.len() >= (rows - 1) * c.stride + c.width, "c too short");
    if depth == 0 {
        if start == Start::Overwrite {
            c.data.chunks_mut(c.stride).take(rows).for_each(|row| row[..c.width].fill(0.0));
        }
        return;
    }
    assert!(b.data.len() >= (depth - 1) * b.stride + b.width, "b too short");
    assert!(a.data.len() > (rows - 1) * a.row + (depth - 1) * a.column, "a too short");
    match isa {
        // SAFETY: `available` has checked that the processor has the instructions.
        Isa::Avx512 => unsafe { product_avx512(start, rows, depth, a, b, c) },
        Isa::Avx2 => unsafe { product_avx2(start, rows, depth, a, b, c) },
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,fma")]
fn product_avx512(start: Start, rows: usize, depth: usize, a: Strided, b: Panels<&[f32]>, c: Panels<&mut [f32]>) {
    product_tiles::<4, 64>(start, rows, depth, a, b, c);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn product_avx2(start: Start, rows: usize, depth: usize, a: Strided, b: Panels<&[f32]>, c: Panels<&mut [f32]>) {
    product_tiles::<2, 32>(start, rows, depth, a, b, c);
}

#[cfg(not(target_arch = "x86_64"))]
fn product_avx512(_: Start, _: usize, _: usize, _: Strided, _: Panels<&[f32]>, _: Panels<&mut [f32]>) {
    unreachable!("no AVX-512 outside x86_64")
}

#[cfg(not(target_arch = "x86_64"))]
fn product_avx2(_: Start, _: usize, _: usize, _: Strided, _: Panels<&[f32]>, _: Panels<&mut [f32]>) {
    unreachable!("no AVX2 outside x86_64")
}

/// Where the tiles write: `c` as a pointer, so that each tile takes its rows without splitting
/// the slice around the other columns.
#[derive(Clone, Copy)]
struct Output {
    data: *mut f32,
    stride: usize,
    start: Start,
}

/// Tiles of `R` rows by up to `W` columns (the widest whole panels left), then the rows that do
/// not fill a tile one at a time.
#[inline(always)]
fn product_tiles<const R: usize, const W: usize>(
    start: Start,
    rows: usize,
    depth: usize,
    a: Strided,
    b: Panels<&[f32]>,
    c: Panels<&mut [f32]>,
) {
    let out = Output { data: c.data.as_mut_ptr(), stride: c.stride, start };
    let mut column = 0;
    while column < c.width {
        let left = c.width - column;
        let taken = match left {
            _ if W >= 64 && left >= 64 => tile_column::<R, 64>(rows, depth, a, &b, out, column),
            _ if W >= 48 && left >= 48 => tile_column::<R, 48>(rows, depth, a, &b, out, column),
            _ if left >= 32 => tile_column::<R, 32>(rows, depth, a, &b, out, column),
            _ => tile_column::<R, 16>(rows, depth, a, &b, out, column),
        };
        column += taken;
    }
}

/// Columns `column..column + W` of every row of `out`; returns `W`.
#[inline(always)]
fn tile_column<const R: usize, const W: usize>(
    rows: usize,
    depth: usize,
    a: Strided,
    b: &Panels<&[f32]>,
    out: Output,
    column: usize,
) -> usize {
    let mut first = 0;
    while first + R <= rows {
        // SAFETY: `product` checked every index these tiles touch against the slices.
        unsafe { tile::<R, W>(first, depth, a, b, out, column) };
        first += R;
    }
    while first < rows {
        // SAFETY: as above.
        unsafe { tile::<1, W>(first, depth, a, b, out, column) };
        first += 1;
    }
    W
}

/// `c[first..first + R][column..column + W] (+)= a(first.., p) b[p][column..column + W]`, the
/// tile held in registers down the whole depth.
///
/// # Safety
/// Every row of the tile and every element read must be inside the operands.
#[inline(always)]
unsafe fn tile<const R: usize, const W: usize>(
    first: usize,
    depth: usize,
    a: Strided,
    b: &Panels<&[f32]>,
    out: Output,
    column: usize,
) {
    let at = |r: usize| (first + r) * out.stride + column;
    let mut acc = [[0f32; W]; R];
    if out.start == Start::Add {
        for (r, row) in acc.iter_mut().enumerate() {
            // SAFETY: the caller's bounds.
            let from = unsafe { std::slice::from_raw_parts(out.data.add(at(r)), W) };
            row.copy_from_slice(from);
        }
    }
    let (a_data, b_data) = (a.data.as_ptr(), b.data.as_ptr());
    for p in 0..depth {
        // SAFETY: the caller's bounds.
        let b_row: &[f32; W] = unsafe { &*(b_data.add(p * b.stride + column) as *const [f32; W]) };
        for (r, row) in acc.iter_mut().enumerate() {
            // SAFETY: the caller's bounds.
            let x = unsafe { *a_data.add((first + r) * a.row + p * a.column) };
            for (v, &w) in row.iter_mut().zip(b_row) {
                *v = x.mul_add(w, *v);
            }
        }
    }
    for (r, row) in acc.iter().enumerate() {
        // SAFETY: the caller's bounds; no other tile writes these elements.
        let to = unsafe { std::slice::from_raw_parts_mut(out.data.add(at(r)), W) };
        to.copy_from_slice(row);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rmvp_dataset::rng::Rng;

    /// A product in f64 from the same operands, and the sum of its terms' magnitudes.
    fn reference(rows: usize, depth: usize, a: Strided, b: &Panels<&[f32]>, c: &Panels<&[f32]>) -> Vec<(f64, f64)> {
        let mut out = Vec::with_capacity(rows * c.width);
        for i in 0..rows {
            for j in 0..c.width {
                let first = c.data[i * c.stride + j] as f64;
                let (mut sum, mut magnitude) = (first, first.abs());
                for p in 0..depth {
                    let term = a.data[i * a.row + p * a.column] as f64 * b.data[p * b.stride + j] as f64;
                    sum += term;
                    magnitude += term.abs();
                }
                out.push((sum, magnitude));
            }
        }
        out
    }

    #[test]
    fn every_tile_shape_sums_what_a_plain_product_sums_and_both_instruction_sets_agree_bit_for_bit() {
        let mut rng = Rng::for_pixel(3, 1, 4);
        // Widths of one to five panels (every tile width and the ones past 64), rows that do and
        // do not fill a tile, `a` read along rows and down columns, strides with slack.
        let cases: Vec<_> =
            [(1, 1, 16, false), (7, 35, 64, false), (9, 64, 48, true), (4, 5, 80, false), (13, 17, 32, true)]
                .into_iter()
                .map(|(rows, depth, width, transposed)| {
                    let a: Vec<f32> = (0..rows * depth).map(|_| rng.normal()).collect();
                    let b: Vec<f32> = (0..depth * (width + 16)).map(|_| rng.normal()).collect();
                    let c: Vec<f32> = (0..rows * (width + 32)).map(|_| rng.normal()).collect();
                    (rows, depth, width, transposed, a, b, c)
                })
                .collect();
        let mut results: Vec<Vec<Vec<f32>>> = Vec::new();
        for isa in [Isa::Avx512, Isa::Avx2].into_iter().filter(|isa| isa.available()) {
            let mut per_isa = Vec::new();
            for (rows, depth, width, transposed, a_data, b, c0) in &cases {
                let (rows, depth, width) = (*rows, *depth, *width);
                let (b_stride, c_stride) = (width + 16, width + 32);
                let a = if *transposed {
                    Strided { data: a_data, row: 1, column: rows }
                } else {
                    Strided { data: a_data, row: depth, column: 1 }
                };
                let mut c = c0.clone();
                product(
                    isa,
                    Start::Add,
                    rows,
                    depth,
                    a,
                    Panels { data: b, stride: b_stride, width },
                    Panels { data: &mut c, stride: c_stride, width },
                );
                let want = reference(
                    rows,
                    depth,
                    a,
                    &Panels { data: b, stride: b_stride, width },
                    &Panels { data: c0, stride: c_stride, width },
                );
                for i in 0..rows {
                    for j in 0..width {
                        let (got, (want, magnitude)) = (c[i * c_stride + j] as f64, want[i * width + j]);
                        // The bound of a sum of depth + 1 rounded terms (Higham's gamma, twice over).
                        let bound = (depth + 1) as f64 * f32::EPSILON as f64 * magnitude;
                        assert!(
                            (got - want).abs() <= bound,
                            "{isa:?} {rows}x{depth}x{width} ({i}, {j}): {got} against {want}"
                        );
                    }
                    // Columns past the width are left alone.
                    assert!(
                        c[i * c_stride + width..(i + 1) * c_stride] == c0[i * c_stride + width..(i + 1) * c_stride]
                    );
                }
                // Overwriting gives what adding to zeros gives, whatever `c` held.
                let mut zeros = c0.clone();
                zeros.chunks_mut(c_stride).for_each(|row| row[..width].fill(0.0));
                let mut overwritten = c0.clone();
                for (start, into) in [(Start::Add, &mut zeros), (Start::Overwrite, &mut overwritten)] {
                    product(
                        isa,
                        start,
                        rows,
                        depth,
                        a,
                        Panels { data: b, stride: b_stride, width },
                        Panels { data: into, stride: c_stride, width },
                    );
                }
                assert!(
                    zeros == overwritten,
                    "{isa:?} {rows}x{depth}x{width}: overwriting differs from adding to zeros"
                );
                per_isa.push(c);
            }
            results.push(per_isa);
        }
        if let [first, rest @ ..] = results.as_slice() {
            for other in rest {
                assert!(first == other, "AVX-512 and AVX2 differ");
            }
        }
    }
}
