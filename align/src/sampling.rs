//! Area-uniform random points on a triangle mesh.

use rmvp_dataset::rng::Rng;
use rmvp_dataset::Mesh;

/// Total surface area of a mesh.
pub fn surface_area(mesh: &Mesh) -> f64 {
    mesh.faces.iter().map(|f| triangle_area(mesh, f)).sum()
}

fn triangle_area(mesh: &Mesh, f: &[u32; 3]) -> f64 {
    let [a, b, c] = f.map(|i| mesh.positions[i as usize].map(|v| v as f64));
    let (u, v) = ([b[0] - a[0], b[1] - a[1], b[2] - a[2]], [c[0] - a[0], c[1] - a[1], c[2] - a[2]]);
    let n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]];
    0.5 * (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt()
}

/// `count` points distributed uniformly over the surface (triangles drawn by area, points
/// uniform inside them), deterministic in `seed`. Empty for a mesh without area.
pub fn sample_surface(mesh: &Mesh, count: usize, seed: u64) -> Vec<[f32; 3]> {
    sample_surface_with_faces(mesh, count, seed).into_iter().map(|(p, _)| p).collect()
}

/// [`sample_surface`], each point with the index of the face it lies on.
pub fn sample_surface_with_faces(mesh: &Mesh, count: usize, seed: u64) -> Vec<([f32; 3], usize)> {
    let mut cdf = Vec::with_capacity(mesh.faces.len());
    let mut total = 0.0;
    for f in &mesh.faces {
        total += triangle_area(mesh, f);
        cdf.push(total);
    }
    if total <= 0.0 {
        return Vec::new();
    }
    let mut rng = Rng::for_pixel(seed, 0, 0);
    (0..count)
        .map(|_| {
            let target = rng.next_f32() as f64 * total;
            let face = cdf.partition_point(|&c| c < target).min(mesh.faces.len() - 1);
            let [a, b, c] = mesh.faces[face].map(|i| mesh.positions[i as usize]);
            // Uniform in the triangle: reflect the unit square's upper half.
            let (mut u, mut v) = (rng.next_f32(), rng.next_f32());
            if u + v > 1.0 {
                (u, v) = (1.0 - u, 1.0 - v);
            }
            ([0, 1, 2].map(|k| a[k] + u * (b[k] - a[k]) + v * (c[k] - a[k])), face)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_spread_by_area() {
        // Two triangles, the second four times the area of the first.
        let mesh = Mesh {
            positions: vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [10.0, 0.0, 0.0],
                [12.0, 0.0, 0.0],
                [10.0, 2.0, 0.0],
            ],
            faces: vec![[0, 1, 2], [3, 4, 5]],
            ..Mesh::default()
        };
        assert!((surface_area(&mesh) - 2.5).abs() < 1e-12);
        let points = sample_surface(&mesh, 50_000, 1);
        let far = points.iter().filter(|p| p[0] >= 10.0).count() as f64 / points.len() as f64;
        assert!((far - 0.8).abs() < 0.01, "{far}");
        assert!(
            points
                .iter()
                .all(|p| (p[0] < 1.0 && p[0] + p[1] <= 1.0 + 1e-6)
                    || (p[0] >= 10.0 && (p[0] - 10.0) + p[1] <= 2.0 + 1e-5))
        );
    }
}
