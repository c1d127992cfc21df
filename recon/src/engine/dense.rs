//! Multilayer perceptrons on row-major batches (`n x width`), forward and backward by SGEMM
//! (`matrixmultiply`), with an optional skip connection and NeuS's geometric initialisation.

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
    fn apply(self, x: &[f32], out: &mut Vec<f32>) {
        out.clear();
        match self {
            Activation::Relu => out.extend(x.iter().map(|&v| v.max(0.0))),
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
fn softplus(beta: f32, x: &[f32], out: &mut Vec<f32>) {
    out.clear();
    out.resize(x.len(), 0.0);
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
}

/// What the forward pass keeps for the backward pass.
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
        Self { layers, activation, skip, inputs }
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

    /// Forward, keeping what backward needs in `cache` when there is one.
    pub fn evaluate(&self, params: &[f32], input: &[f32], rows: usize, mut cache: Option<&mut MlpCache>) -> Vec<f32> {
        debug_assert_eq!(input.len(), rows * self.inputs);
        let hidden = self.layers.len() - 1;
        if let Some(c) = cache.as_deref_mut() {
            c.rows = rows;
            c.layer_inputs = self.layers.iter().map(|l| Vec::with_capacity(rows * l.inputs)).collect();
            c.pre = self.layers[..hidden].iter().map(|l| Vec::with_capacity(rows * l.outputs)).collect();
        }
        let mut result = Vec::with_capacity(rows * self.outputs());
        let (mut h, mut out) = (Vec::new(), Vec::new());
        for first in (0..rows).step_by(ROW_BLOCK) {
            let n = ROW_BLOCK.min(rows - first);
            let block_input = &input[first * self.inputs..(first + n) * self.inputs];
            h.clear();
            h.extend_from_slice(block_input);
            for (l, layer) in self.layers.iter().enumerate() {
                if self.skip == Some(l) {
                    h = concat_skip(&h, block_input, n, layer.inputs - self.inputs, self.inputs);
                }
                let bias = &params[layer.bias..layer.bias + layer.outputs];
                out.clear();
                (0..n).for_each(|_| out.extend_from_slice(bias));
                gemm(
                    n,
                    layer.inputs,
                    layer.outputs,
                    (&h, layer.inputs as isize, 1),
                    (&params[layer.weight..], 1, layer.inputs as isize),
                    1.0,
                    &mut out,
                );
                if let Some(c) = cache.as_deref_mut() {
                    c.layer_inputs[l].extend_from_slice(&h);
                }
                if l == hidden {
                    result.extend_from_slice(&out);
                } else {
                    self.activation.apply(&out, &mut h);
                    if let Some(c) = cache.as_deref_mut() {
                        c.pre[l].extend_from_slice(&out);
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
        let mut d_input = Vec::with_capacity(rows * self.inputs);
        for first in (0..rows).step_by(ROW_BLOCK) {
            let n = ROW_BLOCK.min(rows - first);
            let mut d = d_output[first * outputs..(first + n) * outputs].to_vec();
            let mut d_input_skip: Option<Vec<f32>> = None;
            for l in (0..self.layers.len()).rev() {
                let layer = &self.layers[l];
                if l + 1 < self.layers.len() {
                    let pre = &cache.pre[l][first * layer.outputs..(first + n) * layer.outputs];
                    self.activation.scale_by_derivative(pre, &mut d);
                }
                let x = &cache.layer_inputs[l][first * layer.inputs..(first + n) * layer.inputs];
                // dW += d^T x, db += column sums of d.
                gemm(
                    layer.outputs,
                    n,
                    layer.inputs,
                    (&d, 1, layer.outputs as isize),
                    (x, layer.inputs as isize, 1),
                    1.0,
                    &mut grad[layer.weight..layer.weight + layer.outputs * layer.inputs],
                );
                let gb = &mut grad[layer.bias..layer.bias + layer.outputs];
                for row in d.chunks(layer.outputs) {
                    gb.iter_mut().zip(row).for_each(|(g, v)| *g += v);
                }
                // dx = d W.
                let mut dx = vec![0f32; n * layer.inputs];
                gemm(
                    n,
                    layer.outputs,
                    layer.inputs,
                    (&d, layer.outputs as isize, 1),
                    (&params[layer.weight..], layer.inputs as isize, 1),
                    0.0,
                    &mut dx,
                );
                if self.skip == Some(l) {
                    let hidden = layer.inputs - self.inputs;
                    let (dh, dskip) = split_skip(&dx, n, hidden, self.inputs);
                    d_input_skip = Some(dskip);
                    d = dh;
                } else {
                    d = dx;
                }
            }
            if let Some(extra) = d_input_skip {
                d.iter_mut().zip(extra).for_each(|(a, b)| *a += b);
            }
            d_input.extend_from_slice(&d);
        }
        d_input
    }
}

/// Rows taken through all the layers together, so that a block's activations stay in the
/// core's cache instead of whole batches going through memory layer by layer. A multiple of
/// matrixmultiply's depth block (256): the weight gradient, a sum over rows, is then added up
/// in the same order as by one product over all rows, and results do not depend on it.
const ROW_BLOCK: usize = 512;

const SKIP_SCALE: f32 = std::f32::consts::FRAC_1_SQRT_2;

fn concat_skip(h: &[f32], input: &[f32], rows: usize, hidden: usize, inputs: usize) -> Vec<f32> {
    let mut out = Vec::with_capacity(rows * (hidden + inputs));
    for r in 0..rows {
        out.extend(h[r * hidden..(r + 1) * hidden].iter().map(|v| v * SKIP_SCALE));
        out.extend(input[r * inputs..(r + 1) * inputs].iter().map(|v| v * SKIP_SCALE));
    }
    out
}

fn split_skip(dx: &[f32], rows: usize, hidden: usize, inputs: usize) -> (Vec<f32>, Vec<f32>) {
    let (mut dh, mut di) = (Vec::with_capacity(rows * hidden), Vec::with_capacity(rows * inputs));
    for row in dx.chunks(hidden + inputs) {
        dh.extend(row[..hidden].iter().map(|v| v * SKIP_SCALE));
        di.extend(row[hidden..].iter().map(|v| v * SKIP_SCALE));
    }
    (dh, di)
}

/// `c (m x n, row-major) = beta c + a (m x k) b (k x n)`; `a` and `b` given with row and column
/// strides.
fn gemm(m: usize, k: usize, n: usize, a: (&[f32], isize, isize), b: (&[f32], isize, isize), beta: f32, c: &mut [f32]) {
    assert!(c.len() >= m * n);
    if m == 0 || n == 0 {
        return;
    }
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
            c.as_mut_ptr(),
            n as isize,
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
