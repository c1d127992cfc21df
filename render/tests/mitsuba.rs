//! Against Mitsuba 3, an independent polarized renderer: render the fixtures' meshes, cameras
//! and environment maps and compare with what Mitsuba rendered (`shared/fixtures`).

use rmvp_dataset::layout::read_scene;
use rmvp_dataset::{Scene, Split};
use rmvp_render::pbrdf::{Interface, Lobes};
use rmvp_render::{render_view, EnvMap, Object, RenderedView, Settings};
use rmvp_testkit::fixture_scenes as fixtures;

fn quantile(mut v: Vec<f64>, q: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * q) as usize]
}

fn render_all(scene: &Scene, spp: u32) -> Vec<RenderedView> {
    let object = Object::new(scene.mesh.as_ref().unwrap(), Interface::Dielectric(1.5), Lobes::Plastic).unwrap();
    let env = EnvMap::new(scene.env_map.as_ref().unwrap()).unwrap();
    scene
        .views
        .iter()
        .enumerate()
        .map(|(i, v)| render_view(&object, &env, &v.camera, Settings { spp, seed: 7 }, i as u32))
        .collect()
}

#[test]
fn agrees_with_mitsuba_on_the_fixtures() {
    for dir in fixtures() {
        let scene = read_scene(&dir).unwrap();
        let renders = render_all(&scene, 64);
        let (mut normal_errors, mut aop_errors) = (Vec::new(), Vec::new());
        for (view, ours) in scene.views.iter().zip(&renders) {
            let theirs = view.mask.as_ref().unwrap();
            let (mut both, mut either) = (0usize, 0usize);
            for (a, b) in ours.mask.data().iter().zip(theirs.data()) {
                both += (*a > 0 && *b > 0) as usize;
                either += (*a > 0 || *b > 0) as usize;
            }
            let iou = both as f64 / either as f64;
            let gt = view.normals.as_ref().unwrap();
            for k in 0..theirs.data().len() {
                if ours.mask.data()[k] > 0 && theirs.data()[k] > 0 {
                    let (a, b) = (&ours.normals.data()[3 * k..3 * k + 3], &gt.data()[3 * k..3 * k + 3]);
                    let cos = (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]) as f64;
                    normal_errors.push(cos.clamp(-1.0, 1.0).acos().to_degrees());
                }
            }
            if view.split == Split::Train {
                let s = view.stokes.as_ref().unwrap();
                let (aop, dop) = s.aop_dop();
                let (our_aop, _) = ours.stokes.aop_dop();
                for k in 0..theirs.data().len() {
                    if ours.mask.data()[k] > 0 && theirs.data()[k] > 0 && dop.data()[k] > 0.05 {
                        let d = (our_aop.data()[k] - aop.data()[k]).rem_euclid(std::f32::consts::PI) as f64;
                        aop_errors.push(d.min(std::f64::consts::PI - d).to_degrees());
                    }
                }
            }
            eprintln!("{} view {}: mask IoU {iou:.4}", dir.display(), view.name);
            assert!(iou >= 0.99, "{}: view {}: mask IoU {iou}", dir.display(), view.name);
        }
        let median_normal = quantile(normal_errors.clone(), 0.5);
        let mean_normal = normal_errors.iter().sum::<f64>() / normal_errors.len() as f64;
        let (aop_median, aop_p90) = (quantile(aop_errors.clone(), 0.5), quantile(aop_errors.clone(), 0.9));
        let within_5 = aop_errors.iter().filter(|&&e| e < 5.0).count() as f64 / aop_errors.len() as f64;
        eprintln!(
            "{}: normal median {median_normal:.3} deg, mean {mean_normal:.3} deg; AoP (DoP > 0.05, {} px) median {aop_median:.2} deg, p90 {aop_p90:.2} deg, {:.1}% within 5 deg",
            dir.display(),
            aop_errors.len(),
            100.0 * within_5
        );
        // Mitsuba's normal images are box-filtered: each pixel the mean over its footprint. Ours
        // agree to medians of 0.05 (bunny) and 0.02 (spot) degrees, means 0.19 and 0.12; the
        // normal at each pixel's centre alone differs from theirs by medians of 0.80 and 0.09,
        // means 1.63 and 0.63 (the geometry is exact: no Monte Carlo noise in either).
        assert!(median_normal < 0.2 && mean_normal < 0.4, "normal error median {median_normal}, mean {mean_normal}");
        // Measured at 64 spp: medians 1.6 (spot) and 2.2 (bunny) degrees, 78-85 % within 5
        // degrees; at 128 spp 1.3 and 1.7. What remains is mostly Monte Carlo noise of both
        // renderers at low DoP (see docs/renderer.md).
        assert!(aop_median < 3.0 && within_5 > 0.7, "AoP median {aop_median}, {within_5} within 5 degrees");
    }
}
