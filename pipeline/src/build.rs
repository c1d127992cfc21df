//! Datasets from posed, masked capture sessions (`rmvp dataset build`): every view with a pose
//! and a mask, lens distortion removed, a sparse training split spread over the viewing
//! directions, the normalisation from the visual hull, written in the NeRSP layout (what the
//! official loader reads) and ours.
//!
//! ```text
//! DATASET/nersp/    the NeRSP layout (training views in cameras.npz, every view in gt/)
//! DATASET/rmvp/     our layout
//! ```

use crate::{Error, Result};
use nalgebra::Vector3;
use rmvp_calib::masks::MASKS_FOLDER;
use rmvp_calib::poses::{PoseSet, POSES_FILE};
use rmvp_calib::scene::posed_scene;
use rmvp_calib::undistort::undistort_view;
use rmvp_dataset::layout::{write_scene, Layout};
use rmvp_dataset::{Camera, Scene};
use std::path::{Path, PathBuf};

/// Which views train.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum TrainViews {
    /// This many, spread over the viewing directions (farthest-point sampling).
    Count(usize),
    /// These, by name.
    Names(Vec<String>),
}

impl std::str::FromStr for TrainViews {
    type Err = String;

    /// `6` (a count) or `000,007,013` (names).
    fn from_str(text: &str) -> std::result::Result<Self, String> {
        match text.parse::<usize>() {
            Ok(0) => Err("at least one training view".into()),
            Ok(n) if !text.contains(',') => Ok(TrainViews::Count(n)),
            _ => {
                Ok(TrainViews::Names(text.split(',').map(|s| s.trim().to_string()).filter(|s| !s.is_empty()).collect()))
            }
        }
    }
}

/// What to build; [`BuildOptions::default`] holds `rmvp dataset build`'s defaults.
#[derive(Clone, Debug, PartialEq)]
pub struct BuildOptions {
    /// The posed, masked session.
    pub session: PathBuf,
    /// The dataset folder.
    pub output: PathBuf,
    /// The training split (NeRSP: 6 sparse views).
    pub train: TrainViews,
}

impl Default for BuildOptions {
    fn default() -> Self {
        Self { session: PathBuf::from("session"), output: PathBuf::from("dataset"), train: TrainViews::Count(6) }
    }
}

/// `count` of `cameras` (name, camera) spread over the directions from which they see
/// `centre`: farthest-point sampling on the unit sphere, from the camera nearest the mean
/// direction. Names in capture order.
pub fn spread_views(cameras: &[(String, Camera)], centre: &Vector3<f64>, count: usize) -> Vec<String> {
    let directions: Vec<Vector3<f64>> = cameras.iter().map(|(_, c)| (c.center().coords - centre).normalize()).collect();
    let mean = directions.iter().sum::<Vector3<f64>>();
    let mut chosen = Vec::new();
    if let Some(first) =
        (0..directions.len()).max_by(|&a, &b| directions[a].dot(&mean).total_cmp(&directions[b].dot(&mean)))
    {
        chosen.push(first);
    }
    while chosen.len() < count.min(directions.len()) {
        let far = (0..directions.len())
            .filter(|i| !chosen.contains(i))
            .max_by(|&a, &b| {
                let gap = |i: usize| {
                    chosen.iter().map(|&c| directions[i].dot(&directions[c])).fold(f64::NEG_INFINITY, f64::max)
                };
                gap(b).total_cmp(&gap(a))
            })
            .expect("views left");
        chosen.push(far);
    }
    chosen.sort_unstable();
    chosen.into_iter().map(|i| cameras[i].0.clone()).collect()
}

/// Build the dataset of `options` and return its scene.
pub fn build_dataset(options: &BuildOptions) -> Result<Scene> {
    let session = &options.session;
    let poses_file = session.join(POSES_FILE);
    if !poses_file.is_file() {
        return Err(Error::Unprepared { session: session.clone(), missing: "camera poses (poses.json)" });
    }
    if !session.join(MASKS_FOLDER).is_dir() {
        return Err(Error::Unprepared { session: session.clone(), missing: "object masks (masks/)" });
    }
    let poses = PoseSet::read(&poses_file)?;
    let cameras: Vec<(String, Camera)> =
        poses.views.iter().filter_map(|v| Some((v.name.clone(), Camera::try_from(&v.camera).ok()?))).collect();
    // The split needs the object's centre: a first scene (all views evaluation) gives it.
    let all = posed_scene(session, &poses, None, &[])?;
    let centre = all.normalization.fixed_view::<3, 1>(0, 3).into_owned();
    let train = match &options.train {
        TrainViews::Count(n) => spread_views(&cameras, &centre, *n),
        TrainViews::Names(names) => names.clone(),
    };
    let mut scene = posed_scene(session, &poses, None, &train)?;
    scene.views = scene.views.iter().map(undistort_view).collect();
    // Training views first, as the layouts number them.
    scene.views.sort_by_key(|v| v.split != rmvp_dataset::Split::Train);
    for layout in [Layout::Nersp, Layout::Rmvp] {
        write_scene(&scene, &options.output.join(layout.name()), layout)?;
    }
    Ok(scene)
}

/// The folder of a built dataset in `layout`.
pub fn layout_folder(dataset: &Path, layout: Layout) -> PathBuf {
    dataset.join(layout.name())
}
