//! Multilayer perceptrons on row-major batches (`n x width`), forward and backward by the panel
//! kernels ([`super::panel`]; `matrixmultiply`'s SGEMM on processors without AVX2), with an
//! optional skip connection and NeuS's geometric initialisation.

use super::panel::{self, padded, Isa, Panels, Start, Strided};
use super::params::{Group, ParamLayout};
use multiversion::multiversion;
use rmvp_dataset::rng::Rng;

/// Activation of the hidden layers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Activation {
    /// `max(x, 0)`.
    Relu,
    /// `ln(1 + exp(beta x)) / beta`.
    Softplus(f32),
}

impl Activation {
    /// `out = f(x)` elementwise.
    fn apply(self, x: &[f32], out: &mut [f32]) {
        match self {
            Activation::Relu => out.iter_mut().zip(x).for_each(|(o, &v)| *o = v.max(0.0)),
            Activation::Softplus(beta) => softplus(beta, x, out),
        }
    }

    /// `d *= f'(x)` elementwise.
    fn scale_by_derivative(self, x: &[f32], d: &mut [f32]) {
        match self {
            Activation::Relu => d.iter_mut().zip(x).for_each(|(g, &v)| *g = if v > 0.0 { *g } else { 0.0 }),
            Activation::Softplus(beta) => scale_by_softplus_derivative(beta, x, d),
        }
    }
}

// The two loops that take most of a training step outside the matrix products, compiled for
// the widest vectors the processor has (AVX-512 or AVX2, chosen at run time). Without `mul_add`
// no multiplication and addition are fused, so every width gives the same bits. Plain `for`
// loops: an iterator's `extend` or `for_each` would call a generic `fold` that is compiled
// once, without the wider instructions.

/// `out = softplus(x)`: `max(x, 0) + log1p(exp(-|beta x|)) / beta`, branch-free so it vectorises.
#[multiversion(targets("x86_64+avx512f", "x86_64+avx2"))]
fn softplus(beta: f32, x: &[f32], out: &mut [f32]) {
    for (o, &v) in out.iter_mut().zip(x) {
        *o = v.max(0.0) + log1p_unit(exp_neg((beta * v).abs())) / beta;
    }
}

/// `d *= softplus'(x)`, i.e. `sigmoid(beta x)`, from `e = exp(-|beta x|)`.
#[multiversion(targets("x86_64+avx512f", "x86_64+avx2"))]
fn scale_by_softplus_derivative(beta: f32, x: &[f32], d: &mut [f32]) {
    for (g, &v) in d.iter_mut().zip(x) {
        let e = exp_neg((beta * v).abs());
        let s = if v >= 0.0 { 1.0 } else { e };
        *g *= s / (1.0 + e);
    }
}

/// `exp(-a)` for `a >= 0` (held at `exp(-87)` beyond), relative error below 3e-7: Cody-Waite range reduction
/// and a degree-6 polynomial, written without branches so that loops vectorise.
#[inline(always)]
pub fn exp_neg(a: f32) -> f32 {
    let x = (-a).max(-87.0);
    // Round to nearest by the 1.5 * 2^23 trick (no libm call without SSE4.1): the sum's low
    // mantissa bits hold the integer n itself, so 2^n is built without a float-to-int cast
    // (a saturating cast that kept this loop from vectorising).
    let shifted = x * std::f32::consts::LOG2_E + 12_582_912.0;
    let n = shifted - 12_582_912.0;
    let r = x - n * 0.693_145_75 - n * 1.428_606_8e-6;
    let p =
        1.0 + r * (1.0 + r * (0.5 + r * (0.166_666_67 + r * (0.041_666_41 + r * (0.008_333_452 + r * 0.001_394_973)))));
    // n in [-126, 0]: bits(shifted) = bits(1.5 * 2^23) + n, and 2^n's exponent field is n + 127.
    let two_n = (shifted.to_bits().wrapping_sub(0x4B40_0000).wrapping_add(127)) << 23;
    p * f32::from_bits(two_n)
}

/// `ln(1 + u)` for `u` in `[0, 1]`, absolute error below 1e-7: `2 atanh(u / (2 + u))` as an odd
/// series (the argument stays below 1/3).
#[inline(always)]
pub fn log1p_unit(u: f32) -> f32 {
    let s = u / (2.0 + u);
    let s2 = s * s;
    let series = 1.0
        + s2 * (1.0 / 3.0 + s2 * (0.2 + s2 * (1.0 / 7.0 + s2 * (1.0 / 9.0 + s2 * (1.0 / 11.0 + s2 * (1.0 / 13.0))))));
    2.0 * s * series
}

#[derive(Clone, Debug)]
struct Dense {
    inputs: usize,
    outputs: usize,
    weight: usize,
    bias: usize,
}

/// A fully connected network: `inputs -> hidden^depth -> outputs`, linear output layer.
#[derive(Clone, Debug)]
pub struct Mlp {
    layers: Vec<Dense>,
    activation: Activation,
    /// Layer index whose input is `[h, x] / sqrt(2)` (NeuS's skip connection).
    skip: Option<usize>,
    inputs: usize,
    products: Products,
}

/// What the forward pass keeps for the backward pass, rows padded to whole panels.
#[derive(Default)]
pub struct MlpCache {
    rows: usize,
    /// Input of every layer (after the skip concatenation).
    layer_inputs: Vec<Vec<f32>>,
    /// Pre-activations of the hidden layers.
    pre: Vec<Vec<f32>>,
}

/// How to initialise an [`Mlp`].
#[derive(Clone, Copy, Debug)]
pub enum Init {
    /// Kaiming-uniform-like weights, zero biases.
    Default,
    /// NeuS/IDR geometric initialisation: the first output approximates the SDF of a sphere of
    /// this radius; inputs past the first 3 (encodings) start with zero weights.
    Sphere(f32),
}

impl Mlp {
    /// Reserve a network in `layout`: `hidden` units in each of `depth` hidden layers.
    pub fn new(
        layout: &mut ParamLayout,
        inputs: usize,
        hidden: usize,
        depth: usize,
        outputs: usize,
        activation: Activation,
        skip: Option<usize>,
    ) -> Self {
        let mut layers = Vec::new();
        let mut width = inputs;
        for l in 0..=depth {
            let out = if l == depth {
                outputs
            } else if skip == Some(l + 1) {
                hidden - inputs
            } else {
                hidden
            };
            let weight = layout.reserve(out * width, Group::Network);
            let bias = layout.reserve(out, Group::Network);
            layers.push(Dense { inputs: width, outputs: out, weight, bias });
            width = if skip == Some(l + 1) { out + inputs } else { out };
        }
        Self { layers, activation, skip, inputs, products: Products::best() }
    }

    /// Number of inputs.
    pub fn inputs(&self) -> usize {
        self.inputs
    }

    /// Number of outputs.
    pub fn outputs(&self) -> usize {
        self.layers.last().expect("at least one layer").outputs
    }

    /// Each layer's `(inputs, outputs, weight offset, bias offset)`; weights are `outputs x
    /// inputs`, row-major (for other engines reading the same parameters).
    pub fn layer_shapes(&self) -> Vec<(usize, usize, usize, usize)> {
        self.layers.iter().map(|l| (l.inputs, l.outputs, l.weight, l.bias)).collect()
    }

    /// The hidden layers' activation.
    pub fn activation(&self) -> Activation {
        self.activation
    }

    /// The layer receiving the skip connection, if any.
    pub fn skip(&self) -> Option<usize> {
        self.skip
    }

    /// Write initial weights into `params`.
    pub fn init(&self, params: &mut [f32], init: Init, rng: &mut Rng) {
        let depth = self.layers.len();
        for (l, layer) in self.layers.iter().enumerate() {
            let (n_in, n_out) = (layer.inputs, layer.outputs);
            // The bias is reserved right after the weights.
            let (w, b) = params[layer.weight..layer.bias + n_out].split_at_mut(n_in * n_out);
            match init {
                Init::Default => {
                    let bound = (6.0 / n_in as f32).sqrt();
                    w.iter_mut().for_each(|v| *v = (2.0 * rng.next_f32() - 1.0) * bound * 0.5);
                    b.fill(0.0);
                }
                Init::Sphere(radius) => {
                    if l + 1 == depth {
                        let mean = (std::f32::consts::PI / n_in as f32).sqrt();
                        w.iter_mut().for_each(|v| *v = mean + 1e-4 * rng.normal());
                        b.fill(-radius);
                    } else {
                        let std = 2f32.sqrt() / (n_out as f32).sqrt();
                        w.iter_mut().for_each(|v| *v = std * rng.normal());
                        b.fill(0.0);
                        if l == 0 {
                            // Encodings start silent: the network begins as a function of x alone.
                            for row in w.chunks_mut(n_in) {
                                row[3..].fill(0.0);
                            }
                        } else if self.skip == Some(l) {
                            // The re-injected encoding (all but its first 3 inputs) starts silent.
                            let first = n_in - self.inputs + 3;
                            for row in w.chunks_mut(n_in) {
                                row[first..].fill(0.0);
                            }
                        }
                    }
                }
            }
        }
    }

    /// `outputs (rows x outputs) = f(inputs (rows x inputs))`, keeping what backward needs.
    pub fn forward(&self, params: &[f32], input: &[f32], rows: usize, cache: &mut MlpCache) -> Vec<f32> {
        self.evaluate(params, input, rows, Some(cache))
    }

    /// Forward without keeping anything (inference).
    pub fn infer(&self, params: &[f32], input: &[f32], rows: usize) -> Vec<f32> {
        self.evaluate(params, input, rows, None)
    }

    /// Forward, keeping what backward needs in `cache` when there is one (otherwise in one
    /// block's worth of scratch).
    pub fn evaluate(&self, params: &[f32], input: &[f32], rows: usize, cache: Option<&mut MlpCache>) -> Vec<f32> {
        debug_assert_eq!(input.len(), rows * self.inputs);
        let mut scratch = MlpCache::default();
        let keep = cache.is_some();
        let cache = cache.unwrap_or(&mut scratch);
        let last = self.layers.len() - 1;
        cache.rows = rows;
        cache.layer_inputs.resize_with(self.layers.len(), Vec::new);
        cache.pre.resize_with(last, Vec::new);
        cache.layer_inputs.iter_mut().chain(&mut cache.pre).for_each(Vec::clear);
        // Room for every row kept at once: the buffers grow block by block without moving.
        let kept = if keep { rows } else { ROW_BLOCK.min(rows) };
        for (l, layer) in self.layers.iter().enumerate() {
            cache.layer_inputs[l].reserve(kept * padded(layer.inputs));
            if l < last {
                cache.pre[l].reserve(kept * padded(layer.outputs));
            }
        }
        let weights = self.products.forward_weights(&self.layers, params);
        let mut result = Vec::with_capacity(rows * self.outputs());
        let mut output_block = vec![0f32; ROW_BLOCK.min(rows) * padded(self.outputs())];
        let mut activated = Vec::new();
        for first in (0..rows).step_by(ROW_BLOCK) {
            let n = ROW_BLOCK.min(rows - first);
            let at = if keep { first } else { 0 };
            // A block's rows are added (zeros) as it starts, right before they are written, or
            // reused in scratch; their padding columns are never written and stay zero.
            for (l, layer) in self.layers.iter().enumerate() {
                cache.layer_inputs[l].resize((at + n) * padded(layer.inputs), 0.0);
                if l < last {
                    cache.pre[l].resize((at + n) * padded(layer.outputs), 0.0);
                }
            }
            let block_input = &input[first * self.inputs..(first + n) * self.inputs];
            let stride = padded(self.inputs);
            let x0 = &mut cache.layer_inputs[0][at * stride..(at + n) * stride];
            for (row, from) in x0.chunks_exact_mut(stride).zip(block_input.chunks_exact(self.inputs)) {
                row[..self.inputs].copy_from_slice(from);
            }
            for (l, layer) in self.layers.iter().enumerate() {
                let (width_in, width_out) = (padded(layer.inputs), padded(layer.outputs));
                let (through, later) = cache.layer_inputs.split_at_mut(l + 1);
                let x = &through[l][at * width_in..(at + n) * width_in];
                let y = if l == last {
                    &mut output_block[..n * width_out]
                } else {
                    &mut cache.pre[l][at * width_out..(at + n) * width_out]
                };
                self.products.forward(layer, params, weights.as_ref().map(|w| w[l].as_slice()), n, x, y);
                if l == last {
                    for row in y.chunks_exact(width_out) {
                        result.extend_from_slice(&row[..layer.outputs]);
                    }
                    continue;
                }
                let next_width = padded(self.layers[l + 1].inputs);
                let next = &mut later[0][at * next_width..(at + n) * next_width];
                if self.skip == Some(l + 1) {
                    activated.resize(y.len(), 0.0);
                    self.activation.apply(y, &mut activated);
                    let rows = next.chunks_exact_mut(next_width).zip(activated.chunks_exact(width_out));
                    for ((to, h), x) in rows.zip(block_input.chunks_exact(self.inputs)) {
                        let (to_h, to_x) = to.split_at_mut(layer.outputs);
                        to_h.iter_mut().zip(h).for_each(|(t, v)| *t = v * SKIP_SCALE);
                        to_x.iter_mut().zip(x).for_each(|(t, v)| *t = v * SKIP_SCALE);
                    }
                } else {
                    self.activation.apply(y, next);
                    if layer.outputs < width_out {
                        next.chunks_exact_mut(width_out).for_each(|row| row[layer.outputs..].fill(0.0));
                    }
                }
            }
        }
        result
    }

    /// Given `d_output` (rows x outputs), add the parameter gradients into `grad` and return the
    /// input gradient (rows x inputs).
    pub fn backward(&self, params: &[f32], cache: &MlpCache, d_output: &[f32], grad: &mut [f32]) -> Vec<f32> {
        let rows = cache.rows;
        let outputs = self.outputs();
        let last = self.layers.len() - 1;
        let weights = self.products.backward_weights(&self.layers, params);
        let mut block_sum = Vec::new();
        let mut d_input = Vec::with_capacity(rows * self.inputs);
        let (mut d, mut dx) = (Vec::new(), Vec::new());
        for first in (0..rows).step_by(ROW_BLOCK) {
            let n = ROW_BLOCK.min(rows - first);
            let width = padded(outputs);
            refill(&mut d, n * width);
            for (to, from) in
                d.chunks_exact_mut(width).zip(d_output[first * outputs..(first + n) * outputs].chunks_exact(outputs))
            {
                to[..outputs].copy_from_slice(from);
            }
            let mut d_skip: Option<Vec<f32>> = None;
            for (l, layer) in self.layers.iter().enumerate().rev() {
                let (width_in, width_out) = (padded(layer.inputs), padded(layer.outputs));
                if l < last {
                    self.activation
                        .scale_by_derivative(&cache.pre[l][first * width_out..(first + n) * width_out], &mut d);
                }
                let x = &cache.layer_inputs[l][first * width_in..(first + n) * width_in];
                self.products.weight_gradient(layer, n, &d, x, &mut block_sum, grad);
                let gb = &mut grad[layer.bias..layer.bias + layer.outputs];
                for row in d.chunks_exact(width_out) {
                    gb.iter_mut().zip(row).for_each(|(g, v)| *g += v);
                }
                dx.resize(n * width_in, 0.0);
                self.products.input_gradient(layer, params, weights.as_ref().map(|w| w[l].as_slice()), n, &d, &mut dx);
                if self.skip == Some(l) {
                    // `dx` is `[dh, dx_input] / sqrt(2)`: the first part goes on down, the second
                    // joins the input gradient.
                    let hidden = layer.inputs - self.inputs;
                    let width_h = padded(hidden);
                    refill(&mut d, n * width_h);
                    let mut skipped = Vec::with_capacity(n * self.inputs);
                    for (to, from) in d.chunks_exact_mut(width_h).zip(dx.chunks_exact(width_in)) {
                        to[..hidden].iter_mut().zip(&from[..hidden]).for_each(|(t, v)| *t = v * SKIP_SCALE);
                        skipped.extend(from[hidden..layer.inputs].iter().map(|v| v * SKIP_SCALE));
                    }
                    d_skip = Some(skipped);
                } else {
                    std::mem::swap(&mut d, &mut dx);
                }
            }
            let width = padded(self.inputs);
            for (r, row) in d.chunks_exact(width).enumerate() {
                let row = &row[..self.inputs];
                match &d_skip {
                    Some(skipped) => {
                        let extra = &skipped[r * self.inputs..(r + 1) * self.inputs];
                        d_input.extend(row.iter().zip(extra).map(|(a, b)| a + b));
                    }
                    None => d_input.extend_from_slice(row),
                }
            }
        }
        d_input
    }
}

/// How the layers' matrix products run: every activation matrix is row-major with rows padded
/// to whole panels ([`panel::padded`]), zeros in the padding, whichever runs them.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Products {
    /// matrixmultiply's SGEMM (processors without AVX2 and FMA).
    Sgemm,
    /// The panel kernels, which need no packing.
    Panels(Isa),
}

impl Products {
    /// The panel kernels where the processor runs them.
    fn best() -> Self {
        Isa::detect().map_or(Products::Sgemm, Products::Panels)
    }

    /// For the panels: each layer's weights transposed, `inputs x padded(outputs)`.
    fn forward_weights(self, layers: &[Dense], params: &[f32]) -> Option<Vec<Vec<f32>>> {
        let Products::Panels(_) = self else { return None };
        let transposed = |layer: &Dense| {
            let width = padded(layer.outputs);
            let mut t = vec![0f32; layer.inputs * width];
            let w = &params[layer.weight..layer.weight + layer.outputs * layer.inputs];
            for (o, row) in w.chunks_exact(layer.inputs).enumerate() {
                row.iter().enumerate().for_each(|(k, &v)| t[k * width + o] = v);
            }
            t
        };
        Some(layers.iter().map(transposed).collect())
    }

    /// For the panels: each layer's weights with padded rows, `outputs x padded(inputs)`.
    fn backward_weights(self, layers: &[Dense], params: &[f32]) -> Option<Vec<Vec<f32>>> {
        let Products::Panels(_) = self else { return None };
        let padded_rows = |layer: &Dense| {
            let width = padded(layer.inputs);
            let mut p = vec![0f32; layer.outputs * width];
            let w = &params[layer.weight..layer.weight + layer.outputs * layer.inputs];
            for (to, from) in p.chunks_exact_mut(width).zip(w.chunks_exact(layer.inputs)) {
                to[..layer.inputs].copy_from_slice(from);
            }
            p
        };
        Some(layers.iter().map(padded_rows).collect())
    }

    /// `y = x W^T + b` over `n` rows (`x`: `n x padded(inputs)`, `y`: `n x padded(outputs)`,
    /// zeros in its padding). The panels add the bias to the product, as SGEMM adds its
    /// product to the bias it is given: the same sum.
    fn forward(self, layer: &Dense, params: &[f32], transposed: Option<&[f32]>, n: usize, x: &[f32], y: &mut [f32]) {
        let (width_in, width_out) = (padded(layer.inputs), padded(layer.outputs));
        let bias = &params[layer.bias..layer.bias + layer.outputs];
        match (self, transposed) {
            (Products::Panels(isa), Some(t)) => {
                panel::product(
                    isa,
                    Start::Overwrite,
                    n,
                    layer.inputs,
                    Strided { data: x, row: width_in, column: 1 },
                    Panels { data: t, stride: width_out, width: width_out },
                    Panels { data: y, stride: width_out, width: width_out },
                );
                for row in y.chunks_exact_mut(width_out) {
                    row.iter_mut().zip(bias).for_each(|(v, b)| *v += b);
                }
            }
            _ => {
                for row in y.chunks_exact_mut(width_out) {
                    row[..layer.outputs].copy_from_slice(bias);
                    row[layer.outputs..].fill(0.0);
                }
                gemm(
                    (n, layer.inputs, layer.outputs),
                    (x, width_in as isize, 1),
                    (&params[layer.weight..], 1, layer.inputs as isize),
                    1.0,
                    (y, width_out),
                );
            }
        }
    }

    /// `dW += d^T x` over `n` rows. The panels sum each [`DEPTH_BLOCK`] rows from zero in
    /// `block_sum` (scratch) and add that into `grad`, as SGEMM sums its depth blocks: on
    /// AVX-512 the two give the same bits.
    fn weight_gradient(
        self,
        layer: &Dense,
        n: usize,
        d: &[f32],
        x: &[f32],
        block_sum: &mut Vec<f32>,
        grad: &mut [f32],
    ) {
        let (width_in, width_out) = (padded(layer.inputs), padded(layer.outputs));
        let grad_w = &mut grad[layer.weight..layer.weight + layer.outputs * layer.inputs];
        let Products::Panels(isa) = self else {
            return gemm(
                (layer.outputs, n, layer.inputs),
                (d, 1, width_out as isize),
                (x, width_in as isize, 1),
                1.0,
                (grad_w, layer.inputs),
            );
        };
        for first in (0..n).step_by(DEPTH_BLOCK) {
            let rows = DEPTH_BLOCK.min(n - first);
            block_sum.resize(layer.outputs * width_in, 0.0);
            panel::product(
                isa,
                Start::Overwrite,
                layer.outputs,
                rows,
                Strided { data: &d[first * width_out..], row: 1, column: width_out },
                Panels { data: &x[first * width_in..], stride: width_in, width: width_in },
                Panels { data: block_sum, stride: width_in, width: width_in },
            );
            for (to, from) in grad_w.chunks_exact_mut(layer.inputs).zip(block_sum.chunks_exact(width_in)) {
                to.iter_mut().zip(from).for_each(|(g, v)| *g += v);
            }
        }
    }

    /// `dx = d W` over `n` rows (`d`: `n x padded(outputs)`, `dx`: `n x padded(inputs)`, all of
    /// it written, zeros in its padding).
    fn input_gradient(
        self,
        layer: &Dense,
        params: &[f32],
        padded_rows: Option<&[f32]>,
        n: usize,
        d: &[f32],
        dx: &mut [f32],
    ) {
        let (width_in, width_out) = (padded(layer.inputs), padded(layer.outputs));
        match (self, padded_rows) {
            (Products::Panels(isa), Some(w)) => panel::product(
                isa,
                Start::Overwrite,
                n,
                layer.outputs,
                Strided { data: d, row: width_out, column: 1 },
                Panels { data: w, stride: width_in, width: width_in },
                Panels { data: dx, stride: width_in, width: width_in },
            ),
            _ => {
                dx.fill(0.0);
                gemm(
                    (n, layer.outputs, layer.inputs),
                    (d, width_out as isize, 1),
                    (&params[layer.weight..], layer.inputs as isize, 1),
                    0.0,
                    (dx, width_in),
                );
            }
        }
    }
}

/// `v = [0; len]`, keeping its allocation.
fn refill(v: &mut Vec<f32>, len: usize) {
    v.clear();
    v.resize(len, 0.0);
}

/// Rows taken through all the layers together, so that a block's activations stay in the
/// core's cache instead of whole batches going through memory layer by layer. A multiple of
/// [`DEPTH_BLOCK`]: the weight gradient, a sum over rows, is then added up in the same order as
/// by one product over all rows, and results do not depend on it.
const ROW_BLOCK: usize = 512;

/// Rows of the weight gradient summed from zero before they are added to it: matrixmultiply's
/// depth block for `f32`, which the panels keep so that the two sum alike.
const DEPTH_BLOCK: usize = 256;

const SKIP_SCALE: f32 = std::f32::consts::FRAC_1_SQRT_2;

/// `c (m x n, rows `c.1` apart) = beta c + a (m x k) b (k x n)`; `a` and `b` given with row and
/// column strides.
fn gemm(
    (m, k, n): (usize, usize, usize),
    a: (&[f32], isize, isize),
    b: (&[f32], isize, isize),
    beta: f32,
    c: (&mut [f32], usize),
) {
    if m == 0 || n == 0 {
        return;
    }
    assert!(c.1 >= n && c.0.len() >= (m - 1) * c.1 + n);
    let max_index =
        |rows: usize, cols: usize, rs: isize, cs: isize| (rows - 1) as isize * rs + (cols - 1) as isize * cs;
    if k > 0 {
        assert!(max_index(m, k, a.1, a.2) < a.0.len() as isize);
        assert!(max_index(k, n, b.1, b.2) < b.0.len() as isize);
    }
    // SAFETY: the asserts above keep every index matrixmultiply computes inside the slices.
    unsafe {
        matrixmultiply::sgemm(
            m,
            k,
            n,
            1.0,
            a.0.as_ptr(),
            a.1,
            a.2,
            b.0.as_ptr(),
            b.1,
            b.2,
            beta,
            c.0.as_mut_ptr(),
            c.1 as isize,
            1,
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_batch_in_row_blocks_gives_what_its_rows_give_one_by_one() {
        // Three blocks, the last partial, through a softplus network with a skip connection.
        let mut layout = ParamLayout::default();
        let (inputs, outputs) = (5, 3);
        let mlp = Mlp::new(&mut layout, inputs, 16, 3, outputs, Activation::Softplus(10.0), Some(2));
        let mut rng = Rng::for_pixel(7, 0, 0);
        let mut params = vec![0f32; layout.len()];
        mlp.init(&mut params, Init::Default, &mut rng);
        params.iter_mut().for_each(|p| *p += 0.1 * rng.normal());
        let rows = 2 * ROW_BLOCK + 37;
        let input: Vec<f32> = (0..rows * inputs).map(|_| rng.normal()).collect();
        let d_output: Vec<f32> = (0..rows * outputs).map(|_| rng.normal()).collect();
        let mut cache = MlpCache::default();
        let out = mlp.forward(&params, &input, rows, &mut cache);
        let mut grad = vec![0f32; params.len()];
        let d_input = mlp.backward(&params, &cache, &d_output, &mut grad);
        let mut grad_rows = vec![0f64; params.len()];
        let close = |a: f32, b: f32, tol: f32| (a - b).abs() <= tol * (1.0 + b.abs());
        for r in 0..rows {
            let mut one = MlpCache::default();
            let o = mlp.forward(&params, &input[r * inputs..(r + 1) * inputs], 1, &mut one);
            let mut g = vec![0f32; params.len()];
            let d = mlp.backward(&params, &one, &d_output[r * outputs..(r + 1) * outputs], &mut g);
            grad_rows.iter_mut().zip(&g).for_each(|(a, b)| *a += *b as f64);
            for (a, b) in out[r * outputs..(r + 1) * outputs].iter().zip(&o) {
                assert!(close(*a, *b, 1e-6), "row {r}: output {a} against {b}");
            }
            for (a, b) in d_input[r * inputs..(r + 1) * inputs].iter().zip(&d) {
                assert!(close(*a, *b, 1e-5), "row {r}: input gradient {a} against {b}");
            }
        }
        for (k, (a, b)) in grad.iter().zip(&grad_rows).enumerate() {
            assert!(close(*a, *b as f32, 1e-4), "parameter {k}: gradient {a} against {b}");
        }
    }

    #[test]
    fn the_panel_kernels_give_what_sgemm_gives() {
        // The fast preset's SDF network (35 inputs: a width of no whole panels), a colour network
        // (ReLU, 3 outputs) and one with a skip connection, each over two blocks and a part.
        let Some(isa) = Isa::detect() else { return };
        let shapes = [
            (35, 64, 2, 16, Activation::Softplus(100.0), None),
            (21, 64, 2, 3, Activation::Relu, None),
            (5, 24, 3, 3, Activation::Softplus(10.0), Some(2)),
            (19, 64, 2, 16, Activation::Softplus(100.0), None),
            (18, 64, 2, 1, Activation::Relu, None),
        ];
        for (inputs, hidden, depth, outputs, activation, skip) in shapes {
            let mut layout = ParamLayout::default();
            let mut mlp = Mlp::new(&mut layout, inputs, hidden, depth, outputs, activation, skip);
            let mut rng = Rng::for_pixel(11, inputs as u32, 0);
            let mut params = vec![0f32; layout.len()];
            mlp.init(&mut params, Init::Default, &mut rng);
            params.iter_mut().for_each(|p| *p += 0.1 * rng.normal());
            for rows in [1usize, 3, 7, 40, 300, 2 * ROW_BLOCK + 91] {
                let input: Vec<f32> = (0..rows * inputs).map(|_| rng.normal()).collect();
                let d_output: Vec<f32> = (0..rows * outputs).map(|_| rng.normal()).collect();
                let mut run = |products| {
                    mlp.products = products;
                    let mut cache = MlpCache::default();
                    let out = mlp.forward(&params, &input, rows, &mut cache);
                    let mut grad = vec![0f32; params.len()];
                    let d_input = mlp.backward(&params, &cache, &d_output, &mut grad);
                    assert_eq!(out, mlp.infer(&params, &input, rows), "{products:?}: inference and training differ");
                    (out, d_input, grad)
                };
                let (plain, fused) = (run(Products::Sgemm), run(Products::Panels(isa)));
                // The panels sum in SGEMM's order (each depth block from zero, in order, by fused
                // multiply-adds): matrixmultiply's AVX-512 kernels give the same bits, others within
                // 1e-5 of each vector's largest.
                for (what, a, b) in [
                    ("output", &plain.0, &fused.0),
                    ("input gradient", &plain.1, &fused.1),
                    ("gradient", &plain.2, &fused.2),
                ] {
                    let shape = format!("{inputs}-{hidden}x{depth}-{outputs} {rows} rows {what}");
                    if isa == Isa::Avx512 {
                        assert!(a == b, "{shape}: the panels and SGEMM differ");
                    }
                    let scale = a.iter().fold(0f32, |m, v| m.max(v.abs()));
                    let worst = a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0f32, f32::max);
                    assert!(worst <= 1e-5 * scale, "{shape}: {worst} of {scale}");
                }
            }
        }
    }

    #[test]
    fn fast_exp_and_log1p_match_libm() {
        for k in 0..=1700 {
            let a = k as f32 * 0.05;
            let (got, want) = (exp_neg(a), (-a as f64).exp());
            assert!(((got as f64 - want) / want).abs() < 3e-7, "exp(-{a}) = {got}, want {want}");
        }
        for k in 0..=1000 {
            let u = k as f32 / 1000.0;
            let (got, want) = (log1p_unit(u), (u as f64).ln_1p());
            assert!((got as f64 - want).abs() < 2e-7, "log1p({u}) = {got}, want {want}");
        }
    }
}
