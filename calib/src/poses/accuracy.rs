//! How far poses are from reference poses (a simulation's truth, another method's result): the
//! rotation error and camera-centre distance of every view, directly, or after the similarity
//! that best maps one set of camera centres onto the other (Umeyama 1991) when the world frame
//! of one set is arbitrary (COLMAP's).

use rmvp_dataset::similarity::{rotation_angle_deg, Similarity};
use rmvp_dataset::Camera;

/// The errors of a set of poses against reference poses of the same views.
#[derive(Clone, Debug, PartialEq)]
pub struct PoseErrors {
    /// Rotation error of each view, degrees.
    pub rotation_deg: Vec<f64>,
    /// Distance of each camera centre from the reference's, in the reference's units.
    pub centre_distance: Vec<f64>,
    /// The similarity applied to the poses before comparing (the identity when compared
    /// directly).
    pub similarity: Similarity,
}

impl PoseErrors {
    /// The largest rotation error, degrees.
    pub fn max_rotation_deg(&self) -> f64 {
        self.rotation_deg.iter().copied().fold(0.0, f64::max)
    }

    /// The largest camera-centre distance.
    pub fn max_centre_distance(&self) -> f64 {
        self.centre_distance.iter().copied().fold(0.0, f64::max)
    }
}

/// Compare `found` with `reference` (the same views, in order): directly, or with
/// `up_to_similarity` after the similarity that maps the found camera centres onto the
/// reference's best.
pub fn pose_errors(found: &[Camera], reference: &[Camera], up_to_similarity: bool) -> PoseErrors {
    let similarity = if up_to_similarity {
        let centres = |cameras: &[Camera]| cameras.iter().map(|c| c.center().coords).collect::<Vec<_>>();
        Similarity::fit(&centres(found), &centres(reference))
    } else {
        Similarity::identity()
    };
    let (mut rotation_deg, mut centre_distance) = (Vec::new(), Vec::new());
    for (f, r) in found.iter().zip(reference) {
        // World-to-camera rotation of the found camera in the reference frame: R_f S^T.
        let moved = f.r * similarity.r.transpose();
        rotation_deg.push(rotation_angle_deg(&(moved * r.r.transpose())));
        centre_distance.push((similarity.apply(&f.center().coords) - r.center().coords).norm());
    }
    PoseErrors { rotation_deg, centre_distance, similarity }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix3, Rotation3, Vector3};

    #[test]
    fn a_known_similarity_is_found_and_removed() {
        let k = Matrix3::new(500.0, 0.0, 320.0, 0.0, 500.0, 240.0, 0.0, 0.0, 1.0);
        let truth: Vec<Camera> = (0..6)
            .map(|i| {
                let r = *Rotation3::from_euler_angles(0.3 * i as f64, -0.2, 0.1 * i as f64).matrix();
                Camera::new(k, r, Vector3::new(i as f64, 2.0, 10.0), 640, 480)
            })
            .collect();
        // The same cameras in a world turned, scaled by 3 and moved: x' = s Q x + u.
        let (s, q, u) = (3.0, *Rotation3::from_euler_angles(0.5, 1.0, -0.4).matrix(), Vector3::new(1.0, -2.0, 5.0));
        let moved: Vec<Camera> = truth
            .iter()
            .map(|c| {
                // x_cam = R x + t = R Q^T (x' - u) / s + t, scaled by s (same pixels).
                let r = c.r * q.transpose();
                Camera::new(k, r, s * c.t - r * u, 640, 480)
            })
            .collect();
        let direct = pose_errors(&moved, &truth, false);
        assert!(direct.max_rotation_deg() > 10.0);
        let fitted = pose_errors(&moved, &truth, true);
        assert!((fitted.similarity.s - 1.0 / s).abs() < 1e-9, "{:?}", fitted.similarity);
        assert!(fitted.max_rotation_deg() < 1e-5 && fitted.max_centre_distance() < 1e-9, "{fitted:?}");
    }
}
