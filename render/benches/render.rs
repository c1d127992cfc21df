//! Six 256x256 views at 64 samples per pixel of a mesh (`RMVP_BENCH_MESH`, else the built-in
//! spot) under the built-in environment: seconds per view (`RMVP_BENCH_SPP` overrides 64). With `RMVP_BENCH_EXPORT=DIR` it also
//! writes the cameras (`cameras.json`), the environment (`env.exr`) and the mesh (`mesh.ply`)
//! so that `bench/render_mitsuba.py` renders the very same views.

use rmvp_dataset::camera::matrix_rows;
use rmvp_dataset::io::{exr, write_bytes_atomically};
use rmvp_dataset::Mesh;
use rmvp_render::envmap::procedural_image;
use rmvp_render::pbrdf::{Interface, Lobes};
use rmvp_render::rig::{framing_distance, rig_intrinsics, Rig};
use rmvp_render::{default_mesh, render_view, EnvMap, Object, Settings};
use std::time::Instant;

fn main() {
    if !std::env::args().any(|a| a == "--bench") {
        return; // run by `cargo test --all-targets` (no `--bench`): measure only under `cargo bench`
    }
    let mesh = match std::env::var_os("RMVP_BENCH_MESH") {
        Some(path) => Mesh::read(std::path::Path::new(&path)).expect("RMVP_BENCH_MESH readable"),
        None => default_mesh(),
    };
    // `RMVP_BENCH_SPP` shortens runs for instruction counting (callgrind); the benchmark is 64.
    let spp = std::env::var("RMVP_BENCH_SPP").ok().and_then(|v| v.parse().ok()).unwrap_or(64u32);
    let (w, h) = (256u32, 256u32);
    let k = rig_intrinsics(w, h);
    let cameras = Rig::Sphere { views: 6 }.cameras(k, w, h, framing_distance(&k, w, h, 1.0, 0.85), 0);
    let env_image = procedural_image();
    let start = Instant::now();
    let object = Object::new(&mesh, Interface::Dielectric(1.5), Lobes::Plastic).unwrap();
    let env = EnvMap::new(&env_image).unwrap();
    let setup = start.elapsed().as_secs_f64();
    let threads = rayon::current_num_threads();
    println!("render benchmark: {} triangles, 6 views {w}x{h} at {spp} spp, {threads} threads", mesh.faces.len());
    println!("  set-up (BVH, environment sampling tables) {setup:.3} s");
    let mut times = Vec::new();
    for (i, camera) in cameras.iter().enumerate() {
        let t = Instant::now();
        let view = render_view(&object, &env, camera, Settings { spp, seed: 0 }, i as u32);
        times.push(t.elapsed().as_secs_f64());
        std::hint::black_box(view);
    }
    let total: f64 = times.iter().sum();
    let rays = 6.0 * (w * h) as f64 * (1.0 + 3.0 * spp as f64);
    println!("  per view: {}", times.iter().map(|t| format!("{t:.3}")).collect::<Vec<_>>().join(" "));
    println!("  {:.3} s per view, about {:.1} M rays/s", total / 6.0, rays / total / 1e6);
    println!("rust_s_per_view {:.4}", total / 6.0);
    if let Some(dir) = std::env::var_os("RMVP_BENCH_EXPORT") {
        let dir = std::path::PathBuf::from(dir);
        let cams: Vec<_> = cameras
            .iter()
            .map(|c| serde_json::json!({"K": matrix_rows(&c.k), "R": matrix_rows(&c.r), "t": [c.t.x, c.t.y, c.t.z], "width": w, "height": h}))
            .collect();
        let json = serde_json::json!({"spp": spp, "cameras": cams});
        write_bytes_atomically(&dir.join("cameras.json"), json.to_string().as_bytes()).unwrap();
        exr::write_exr(&dir.join("env.exr"), &env_image, &["R", "G", "B"]).unwrap();
        mesh.write(&dir.join("mesh.ply")).unwrap();
    }
}
