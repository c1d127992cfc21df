//! The SDF of a hash-grid field on an NVIDIA GPU: CUDA kernels compiled at run time by NVRTC
//! and launched through the driver API (cudarc, both libraries loaded when first used, so the
//! binary runs and the CPU engine works on machines without them). Forward only: surface
//! extraction's SDF grid and vertex normals; training stays on the CPU engine.

use crate::extract::SdfEvaluator;
use crate::model::Field;
use crate::{Error, Result};
use cudarc::driver::{CudaContext, CudaFunction, CudaSlice, CudaStream, LaunchConfig, PushKernelArg};
use cudarc::nvrtc::{compile_ptx_with_opts, CompileOptions};
use std::sync::Arc;

const SOURCE: &str = include_str!("sdf.cu");
const THREADS: u32 = 128;

/// A field's SDF network and hash grid resident on the GPU, with its kernels.
pub struct CudaSdf {
    stream: Arc<CudaStream>,
    params: CudaSlice<f32>,
    points_kernel: CudaFunction,
    grid_kernel: CudaFunction,
    shared_bytes: u32,
    device: String,
}

fn cuda_error(what: &str, e: impl std::fmt::Debug) -> Error {
    Error::Cuda(format!("{what}: {e:?}"))
}

impl CudaSdf {
    /// Compile the kernels for `field`'s shape and upload `params` under `level_weight`, on
    /// GPU 0. Fails, saying why, without a CUDA driver or NVRTC, without a GPU, or for a field
    /// the kernels do not cover (the paper preset's positional-encoding MLP).
    pub fn new(field: &Field, params: &[f32], level_weight: &[f32]) -> Result<Self> {
        let source = kernel_source(field, level_weight)?;
        let ctx = context()?;
        let device = ctx.name().map_err(|e| cuda_error("device name", e))?;
        let (major, minor) = ctx.compute_capability().map_err(|e| cuda_error("compute capability", e))?;
        let options =
            CompileOptions { options: vec![format!("--gpu-architecture=sm_{major}{minor}")], ..Default::default() };
        let ptx = compile_ptx_with_opts(source, options).map_err(|e| cuda_error("compiling the SDF kernels", e))?;
        let module = ctx.load_module(ptx).map_err(|e| cuda_error("loading the SDF kernels", e))?;
        let load = |name| module.load_function(name).map_err(|e| cuda_error(name, e));
        let (points_kernel, grid_kernel) = (load("sdf_points")?, load("sdf_grid")?);
        let stream = ctx.default_stream();
        let params = stream.clone_htod(params).map_err(|e| cuda_error("uploading the parameters", e))?;
        let shared_bytes = (4 * network_floats(field)) as u32;
        Ok(Self { stream, params, points_kernel, grid_kernel, shared_bytes, device })
    }

    /// The GPU's name.
    pub fn device(&self) -> &str {
        &self.device
    }

    fn config(&self, threads: u64) -> LaunchConfig {
        let blocks = threads.div_ceil(THREADS as u64) as u32;
        LaunchConfig { grid_dim: (blocks, 1, 1), block_dim: (THREADS, 1, 1), shared_mem_bytes: self.shared_bytes }
    }
}

/// GPU 0's context, or why CUDA cannot run here (no driver, no NVRTC, no GPU).
fn context() -> Result<Arc<CudaContext>> {
    // SAFETY: only probes whether the shared libraries can be opened.
    if !unsafe { cudarc::driver::sys::is_culib_present() } {
        return Err(Error::Cuda("no CUDA driver (libcuda.so.1) found: no NVIDIA GPU here".into()));
    }
    if !unsafe { cudarc::nvrtc::sys::is_culib_present() } {
        return Err(Error::Cuda("NVRTC (libnvrtc.so) not found: install the CUDA runtime compiler".into()));
    }
    CudaContext::new(0).map_err(|e| cuda_error("no usable GPU", e))
}

/// The name of the GPU the kernels would run on, or why they cannot run here.
pub fn probe() -> Result<String> {
    context()?.name().map_err(|e| cuda_error("device name", e))
}

impl SdfEvaluator for CudaSdf {
    fn sdf(&self, points: &[f32]) -> Result<Vec<f32>> {
        let n = points.len() / 3;
        if n == 0 {
            return Ok(Vec::new());
        }
        let points = self.stream.clone_htod(points).map_err(|e| cuda_error("uploading points", e))?;
        let mut out = self.stream.alloc_zeros::<f32>(n).map_err(|e| cuda_error("allocating the SDF", e))?;
        let count = n as i32;
        let mut launch = self.stream.launch_builder(&self.points_kernel);
        launch.arg(&self.params).arg(&points).arg(&mut out).arg(&count);
        // SAFETY: the kernel reads n points and writes n values, the sizes allocated above.
        unsafe { launch.launch(self.config(n as u64)) }.map_err(|e| cuda_error("sdf_points", e))?;
        self.stream.clone_dtoh(&out).map_err(|e| cuda_error("downloading the SDF", e))
    }

    fn sdf_grid(&self, n: usize) -> Result<Vec<f32>> {
        let side = n as u64 + 1;
        let count = side * side * side;
        let mut out =
            self.stream.alloc_zeros::<f32>(count as usize).map_err(|e| cuda_error("allocating the grid", e))?;
        let cells = n as i32;
        let mut launch = self.stream.launch_builder(&self.grid_kernel);
        launch.arg(&self.params).arg(&mut out).arg(&cells);
        // SAFETY: the kernel writes (n + 1)^3 values, the size allocated above.
        unsafe { launch.launch(self.config(count)) }.map_err(|e| cuda_error("sdf_grid", e))?;
        self.stream.clone_dtoh(&out).map_err(|e| cuda_error("downloading the grid", e))
    }
}

/// Floats of the network that the kernels keep in shared memory (the SDF row of the last layer).
fn network_floats(field: &Field) -> usize {
    let layers = field.mlp().layer_shapes();
    let last = layers.len() - 1;
    layers
        .iter()
        .enumerate()
        .map(|(l, &(inputs, outputs, ..))| if l == last { inputs + 1 } else { (inputs + 1) * outputs })
        .sum()
}

/// The kernel source with `field`'s shape defined in front, or why the kernels cannot run it.
fn kernel_source(field: &Field, level_weight: &[f32]) -> Result<String> {
    let unsupported = |why: &str| Err(Error::Cuda(format!("the CUDA kernels evaluate hash-grid fields only: {why}")));
    let Some(grid) = field.grid() else { return unsupported("this field has no hash grid (the paper preset)") };
    let mlp = field.mlp();
    let crate::engine::Activation::Softplus(beta) = mlp.activation() else { return unsupported("ReLU network") };
    if mlp.skip().is_some() {
        return unsupported("the network has a skip connection");
    }
    let layers = mlp.layer_shapes();
    let hidden = layers[0].1;
    let levels = grid.levels();
    let list = |values: Vec<String>| format!("{{{}}}", values.join(", "));
    let weights = list(layers.iter().map(|l| l.2.to_string()).collect());
    let biases = list(layers.iter().map(|l| l.3.to_string()).collect());
    let resolutions = list(grid.resolutions().iter().map(|r| format!("{r}u")).collect());
    let weights_of_levels =
        list((0..levels).map(|l| format!("{:e}f", level_weight.get(l).copied().unwrap_or(0.0))).collect());
    let mut head = String::new();
    for (name, value) in [
        ("LEVELS", levels.to_string()),
        ("TABLE", format!("{}u", grid.table_entries())),
        ("GRID_OFFSET", format!("{}ull", grid.offset())),
        ("INPUTS", mlp.inputs().to_string()),
        ("HIDDEN", hidden.to_string()),
        ("HIDDEN_LAYERS", (layers.len() - 1).to_string()),
        ("BETA", format!("{beta:e}f")),
        ("WEIGHT_OFFSETS", weights),
        ("BIAS_OFFSETS", biases),
        ("RESOLUTIONS", resolutions),
        ("LEVEL_WEIGHTS", weights_of_levels),
    ] {
        head.push_str(&format!("#define {name} {value}\n"));
    }
    Ok(head + SOURCE)
}
