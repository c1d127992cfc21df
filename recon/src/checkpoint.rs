//! Checkpoints: a run's parameters, optimiser state and iteration with its configuration and
//! options, written atomically and read back so that a resumed run repeats an uninterrupted one
//! bit for bit. A header is compared with the run before anything is built from it.

use crate::data::TrainingSet;
use crate::occupancy::OccupancyGrid;
use crate::options::ReconOptions;
use crate::train::{TrainConfig, Trainer};
use crate::{Error, Result};
use rmvp_dataset::io::atomic::write_bytes_atomically;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Save `trainer`'s parameters, optimiser state, occupancy grid and iteration to `path`
/// (atomically), with the options the run was started with where the caller gives them.
pub fn save(trainer: &Trainer, options: Option<&ReconOptions>, path: &Path) -> Result<()> {
    let occupancy = trainer.occupancy().map_or(&[][..], OccupancyGrid::values);
    let header = serde_json::to_vec(&CheckpointHeader {
        format: CHECKPOINT_FORMAT.into(),
        config: trainer.config.clone(),
        options: options.cloned(),
        iteration: trainer.iteration,
        adam_steps: trainer.adam.steps,
        parameters: trainer.params.len(),
        occupancy: occupancy.len(),
    })
    .expect("plain data");
    let mut bytes = Vec::with_capacity(16 + header.len() + 12 * trainer.params.len() + 4 * occupancy.len());
    bytes.extend_from_slice(CHECKPOINT_MAGIC);
    bytes.extend_from_slice(&(header.len() as u64).to_le_bytes());
    bytes.extend_from_slice(&header);
    for v in [&trainer.params[..], &trainer.adam.m, &trainer.adam.v, occupancy] {
        for x in v.iter() {
            bytes.extend_from_slice(&x.to_le_bytes());
        }
    }
    Ok(write_bytes_atomically(path, &bytes)?)
}

/// Restore a run from a checkpoint written by [`save`]; the training
/// set must be the one it was trained on. The checkpoint's header is compared with the run's
/// `config` (and with `options`, where both have them) before anything is built from it: a
/// header may declare any model, and only the run's is built.
pub fn load(path: &Path, set: TrainingSet, config: &TrainConfig, options: Option<&ReconOptions>) -> Result<Trainer> {
    let bad = |m: &str| Error::BadCheckpoint { path: path.to_path_buf(), problem: m.to_string() };
    let (header, len, file_len) = checkpoint_header(path)?;
    let changed = match (&header.options, options) {
        (Some(recorded), Some(now)) => recorded.training_differences(now),
        _ => Vec::new(),
    };
    if !changed.is_empty() || header.config != *config {
        let changed = if changed.is_empty() { "the training configuration".into() } else { changed.join(", ") };
        return Err(Error::CheckpointSettings { path: path.to_path_buf(), changed });
    }
    // The run samples through an occupancy grid exactly when it renders only weighted samples.
    let occupancy = if config.sampling.skips_empty_space() { OccupancyGrid::VALUES } else { 0 };
    if header.occupancy != occupancy {
        return Err(bad(&format!("{} occupancy grid values, the run has {occupancy}", header.occupancy)));
    }
    // The file's size against its header's counts before anything is read or built.
    let body = file_len - 16 - len as u64;
    let expected = 12u64.saturating_mul(header.parameters as u64) + 4 * occupancy as u64;
    if body != expected {
        let state = if body < expected { "truncated" } else { "too long" };
        return Err(bad(&format!("{state}: {body} bytes of parameters and optimiser state, expected {expected}")));
    }
    let mut trainer = Trainer::new(config.clone(), set);
    let n = trainer.params.len();
    if header.parameters != n {
        return Err(bad(&format!("{} parameters, the model has {n}", header.parameters)));
    }
    let bytes = rmvp_dataset::io::input::read_bytes_limited(path, file_len)?;
    let floats: Vec<f32> = bytes
        .get(16 + len..)
        .unwrap_or_default()
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes")))
        .collect();
    if floats.len() != 3 * n + occupancy {
        return Err(bad("changed while read"));
    }
    if floats[..n].iter().any(|p| !p.is_finite()) {
        return Err(bad("non-finite parameters"));
    }
    let mut adam = trainer.adam.clone();
    adam.m = floats[n..2 * n].to_vec();
    adam.v = floats[2 * n..3 * n].to_vec();
    adam.steps = header.adam_steps;
    let grid = OccupancyGrid::from_values(&floats[3 * n..]);
    if grid.as_ref().is_some_and(|g| g.values().iter().any(|v| !v.is_finite())) {
        return Err(bad("non-finite occupancy grid"));
    }
    trainer.restore(floats[..n].to_vec(), adam, header.iteration, grid);
    Ok(trainer)
}

const CHECKPOINT_MAGIC: &[u8; 8] = b"RMVPCKPT";
/// The checkpoint's format: 3 since the occupancy grid follows the optimiser state.
const CHECKPOINT_FORMAT: &str = "rmvp-recon-checkpoint-3";

/// The options a checkpoint's run was started with (`None` for a run started without them).
pub fn recorded_options(path: &Path) -> Result<Option<ReconOptions>> {
    Ok(checkpoint_header(path)?.0.options)
}

/// The training configuration a checkpoint's run trained with.
pub fn recorded_config(path: &Path) -> Result<TrainConfig> {
    Ok(checkpoint_header(path)?.0.config)
}

/// The most bytes a checkpoint's header (JSON: the configuration and options) may have.
const MAX_CHECKPOINT_HEADER_BYTES: u64 = 1 << 20;

/// A checkpoint's header, its length in bytes and the file's length: only the header is read.
fn checkpoint_header(path: &Path) -> Result<(CheckpointHeader, usize, u64)> {
    use std::io::Read;
    let bad = |m: &str| Error::BadCheckpoint { path: path.to_path_buf(), problem: m.to_string() };
    let file = rmvp_dataset::io::input::open_regular(path)?;
    let file_len = file.metadata().map_err(|e| rmvp_dataset::Error::io(path, e))?.len();
    let mut head = Vec::new();
    let mut reader = file.take(16 + MAX_CHECKPOINT_HEADER_BYTES);
    reader.by_ref().take(16).read_to_end(&mut head).map_err(|e| rmvp_dataset::Error::io(path, e))?;
    if head.len() < 16 || &head[..8] != CHECKPOINT_MAGIC {
        return Err(bad("not an rmvp checkpoint"));
    }
    let len = u64::from_le_bytes(head[8..16].try_into().expect("8 bytes"));
    if len > MAX_CHECKPOINT_HEADER_BYTES || 16 + len > file_len {
        return Err(bad("truncated header"));
    }
    let mut text = Vec::with_capacity(len as usize);
    reader.take(len).read_to_end(&mut text).map_err(|e| rmvp_dataset::Error::io(path, e))?;
    if text.len() as u64 != len {
        return Err(bad("truncated header"));
    }
    let header: CheckpointHeader = serde_json::from_slice(&text).map_err(|e| bad(&format!("header: {e}")))?;
    if header.format != CHECKPOINT_FORMAT {
        return Err(bad(&format!("format {}, this version reads {CHECKPOINT_FORMAT}", header.format)));
    }
    Ok((header, len as usize, file_len))
}

#[derive(Serialize, Deserialize)]
struct CheckpointHeader {
    format: String,
    config: TrainConfig,
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        deserialize_with = "crate::options::deserialize_recorded_option"
    )]
    options: Option<ReconOptions>,
    iteration: u32,
    adam_steps: u32,
    parameters: usize,
    /// Values of the occupancy grid after the optimiser state (0: none).
    #[serde(default)]
    occupancy: usize,
}
