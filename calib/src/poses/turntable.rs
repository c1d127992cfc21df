//! Poses from the turntable: each view's camera is the camera of its recorded turntable
//! position in a rig calibration, a session captured (and posed, with the board) at the same
//! positions. Objects then need no board: the rig's poses carry over.

use super::{PoseMethod, PoseSet, ViewPose, POSES_FILE};
use crate::intrinsics::Rejected;
use crate::Result;
use rmvp_dataset::session::SessionManifest;
use std::collections::BTreeMap;
use std::path::Path;

/// Pose the session in `dir` from the posed rig session in `rig` (its `poses.json` and the
/// turntable positions both sessions recorded); at least `min_views` must be posed.
pub fn turntable_poses(dir: &Path, rig: &Path, min_views: usize) -> Result<PoseSet> {
    let (rig_manifest, rig_poses) = (SessionManifest::read(rig)?, PoseSet::read(&rig.join(POSES_FILE))?);
    let by_position: BTreeMap<i64, &ViewPose> = rig_manifest
        .views
        .iter()
        .filter_map(|v| Some((v.turntable_position?, rig_poses.views.iter().find(|p| p.name == v.name)?)))
        .collect();
    let manifest = SessionManifest::read(dir)?;
    manifest.require_views(dir)?;
    let (mut views, mut failed) = (Vec::new(), Vec::new());
    for view in &manifest.views {
        let reject = |reason: String| Rejected { name: view.name.clone(), reason };
        match view.turntable_position {
            None => failed.push(reject("no turntable position recorded".into())),
            Some(position) => match by_position.get(&position) {
                Some(pose) => views.push(ViewPose { name: view.name.clone(), ..(*pose).clone() }),
                None => {
                    failed.push(reject(format!("turntable position {position} is not posed in the rig calibration")))
                }
            },
        }
    }
    let world = format!("the rig calibration's ({}): {}", rig.display(), rig_poses.world);
    PoseSet { method: PoseMethod::Turntable, world, views, failed }.require(min_views)
}
