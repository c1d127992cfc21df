//! Meshes with analytic answers.

use rmvp_dataset::Mesh;

/// A unit sphere: an icosahedron subdivided `levels` times (20 x 4^levels triangles), vertices on
/// the sphere, exact vertex normals. For tests and demos with analytic answers.
pub fn icosphere(levels: usize) -> Mesh {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut v: Vec<[f64; 3]> = vec![
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ];
    let mut f: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    let unit = |p: [f64; 3]| {
        let n = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
        [p[0] / n, p[1] / n, p[2] / n]
    };
    v.iter_mut().for_each(|p| *p = unit(*p));
    for _ in 0..levels {
        let mut cache = std::collections::HashMap::new();
        let mut mid = |a: u32, b: u32, v: &mut Vec<[f64; 3]>| {
            *cache.entry((a.min(b), a.max(b))).or_insert_with(|| {
                let (p, q) = (v[a as usize], v[b as usize]);
                v.push(unit([(p[0] + q[0]) / 2.0, (p[1] + q[1]) / 2.0, (p[2] + q[2]) / 2.0]));
                v.len() as u32 - 1
            })
        };
        f = f
            .iter()
            .flat_map(|&[a, b, c]| {
                let (ab, bc, ca) = (mid(a, b, &mut v), mid(b, c, &mut v), mid(c, a, &mut v));
                [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
            })
            .collect();
    }
    let positions: Vec<[f32; 3]> = v.iter().map(|p| p.map(|x| x as f32)).collect();
    Mesh { normals: Some(positions.clone()), positions, faces: f, vertex_properties: Vec::new() }
}

/// A unit sphere with fine bumps: the icosphere of `levels` displaced along its normals by a
/// sum of `waves` plane waves of frequencies 8 to 20 and amplitudes summing to about
/// `amplitude` (deterministic in `seed`), scaled back into the unit sphere. Normals from the
/// faces.
pub fn bumpy_sphere(levels: usize, waves: usize, amplitude: f64, seed: u64) -> Mesh {
    let mut rng = rmvp_dataset::rng::Rng::for_pixel(seed, 0, 0);
    let mut uniform = || rng.next_f32() as f64;
    let waves: Vec<([f64; 3], f64, f64, f64)> = (0..waves)
        .map(|_| {
            let (z, phi) = (2.0 * uniform() - 1.0, std::f64::consts::TAU * uniform());
            let s = (1.0 - z * z).sqrt();
            let direction = [s * phi.cos(), s * phi.sin(), z];
            (direction, 8.0 + 12.0 * uniform(), std::f64::consts::TAU * uniform(), 0.5 + uniform())
        })
        .collect();
    let total: f64 = waves.iter().map(|w| w.3).sum();
    let mut mesh = icosphere(levels);
    for p in &mut mesh.positions {
        let n = p.map(|v| v as f64);
        let bump: f64 = waves
            .iter()
            .map(|(d, f, phase, a)| a * (f * (n[0] * d[0] + n[1] * d[1] + n[2] * d[2]) + phase).sin())
            .sum::<f64>()
            * amplitude
            / total
            * 2.0;
        *p = n.map(|v| (v * (1.0 + bump)) as f32);
    }
    let radius = mesh.radius();
    mesh.positions.iter_mut().for_each(|p| *p = p.map(|v| v / radius));
    mesh.normals = None;
    mesh
}

/// A `(p, q)` torus knot (the trefoil is `(2, 3)`) as a tube of radius `tube` around the
/// curve, `segments` rings of `sides` vertices, scaled into the unit sphere. Thin parts and
/// narrow gaps where the tube passes itself.
pub fn torus_knot(p: u32, q: u32, tube: f64, segments: usize, sides: usize) -> Mesh {
    let curve = |t: f64| {
        let r = 2.0 + (q as f64 * t).cos();
        [r * (p as f64 * t).cos(), r * (p as f64 * t).sin(), -(q as f64 * t).sin()]
    };
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let cross =
        |a: [f64; 3], b: [f64; 3]| [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
    let unit = |a: [f64; 3]| {
        let n = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt().max(1e-12);
        a.map(|v| v / n)
    };
    let mut positions = Vec::with_capacity(segments * sides);
    for i in 0..segments {
        let t = std::f64::consts::TAU * i as f64 / segments as f64;
        let (c, ahead) = (curve(t), curve(t + 1e-4));
        let tangent = unit(sub(ahead, c));
        // A frame turning with the curve: the normal towards the knot's axis-free direction.
        let normal = unit(cross(tangent, [0.0, 0.0, 1.0]));
        let binormal = cross(tangent, normal);
        for j in 0..sides {
            let a = std::f64::consts::TAU * j as f64 / sides as f64;
            let offset = [0, 1, 2].map(|k| tube * (a.cos() * normal[k] + a.sin() * binormal[k]));
            positions.push([0, 1, 2].map(|k| c[k] + offset[k]));
        }
    }
    unit_sphere_mesh(positions, tube_faces(segments, sides))
}

/// A ring lying in the XZ plane around +Y (a pool float): a tube of radius `tube` around a
/// circle of radius 1, `segments` rings of `sides` vertices, scaled into the unit sphere.
pub fn torus(tube: f64, segments: usize, sides: usize) -> Mesh {
    let mut positions = Vec::with_capacity(segments * sides);
    for i in 0..segments {
        let (sa, ca) = (std::f64::consts::TAU * i as f64 / segments as f64).sin_cos();
        for j in 0..sides {
            let (sb, cb) = (std::f64::consts::TAU * j as f64 / sides as f64).sin_cos();
            let r = 1.0 + tube * cb;
            positions.push([r * ca, tube * sb, r * sa]);
        }
    }
    unit_sphere_mesh(positions, tube_faces(segments, sides))
}

/// The triangles of a closed tube of `segments` rings of `sides` vertices each, stored ring by
/// ring, counter-clockwise seen from outside for the rings of [`torus`] and [`torus_knot`].
fn tube_faces(segments: usize, sides: usize) -> Vec<[u32; 3]> {
    let mut faces = Vec::with_capacity(2 * segments * sides);
    for i in 0..segments {
        for j in 0..sides {
            let at = |i: usize, j: usize| ((i % segments) * sides + j % sides) as u32;
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            faces.extend([[a, c, b], [a, d, c]]);
        }
    }
    faces
}

/// A star-shaped prism with `teeth` sharp teeth (outer radius 1, inner `inner`), `height`
/// tall: flat faces meeting at sharp creases (each face its own vertices and normal).
pub fn gear(teeth: usize, inner: f64, height: f64) -> Mesh {
    let outline: Vec<[f64; 2]> = (0..2 * teeth)
        .map(|k| {
            let a = std::f64::consts::PI * k as f64 / teeth as f64;
            let r = if k % 2 == 0 { 1.0 } else { inner };
            [r * a.cos(), r * a.sin()]
        })
        .collect();
    let (mut positions, mut normals, mut faces) = (Vec::new(), Vec::new(), Vec::new());
    let h = height / 2.0;
    // Caps: fans around the centre (the outline is star-shaped about it).
    for (y, sign) in [(h, 1.0), (-h, -1.0)] {
        let centre = positions.len() as u32;
        positions.push([0.0, y, 0.0]);
        for p in &outline {
            positions.push([p[0], y, p[1]]);
        }
        normals.extend(std::iter::repeat_n([0.0, sign, 0.0], outline.len() + 1));
        for k in 0..outline.len() as u32 {
            let (a, b) = (centre + 1 + k, centre + 1 + (k + 1) % outline.len() as u32);
            faces.push(if sign > 0.0 { [centre, b, a] } else { [centre, a, b] });
        }
    }
    // Sides: one quad per outline edge.
    for k in 0..outline.len() {
        let (p, q) = (outline[k], outline[(k + 1) % outline.len()]);
        let (dx, dz) = (q[0] - p[0], q[1] - p[1]);
        let length = (dx * dx + dz * dz).sqrt();
        let normal = [dz / length, 0.0, -dx / length];
        let base = positions.len() as u32;
        positions.extend([[p[0], -h, p[1]], [q[0], -h, q[1]], [q[0], h, q[1]], [p[0], h, p[1]]]);
        normals.extend([normal; 4]);
        faces.extend([[base, base + 2, base + 1], [base, base + 3, base + 2]]);
    }
    let mut mesh = unit_sphere_mesh(positions, faces);
    mesh.normals = Some(normals.iter().map(|n| n.map(|v| v as f32)).collect());
    mesh
}

/// A thick-walled bowl: a surface of revolution about +Y whose cavity is `depth` (0 to 1) of
/// its outer radius deep, walls `wall` thick, with a rounded rim. A deep concavity that
/// outer views cannot see into.
pub fn bowl(depth: f64, wall: f64, segments: usize) -> Mesh {
    // Profile from the inner bottom (on the axis) up the cavity, over the rim, down the outside
    // to the outer bottom (on the axis): (radius, height).
    let steps = 48;
    let mut profile: Vec<[f64; 2]> = Vec::new();
    let inner = 1.0 - wall;
    for k in 0..=steps {
        let a = std::f64::consts::FRAC_PI_2 * k as f64 / steps as f64;
        profile.push([inner * a.sin(), -depth * a.cos()]);
    }
    for k in 1..steps {
        let a = std::f64::consts::PI * k as f64 / steps as f64;
        profile.push([1.0 - wall / 2.0 - wall / 2.0 * a.cos(), wall / 2.0 * a.sin()]);
    }
    for k in (0..=steps).rev() {
        let a = std::f64::consts::FRAC_PI_2 * k as f64 / steps as f64;
        profile.push([a.sin(), -(depth + wall) * a.cos()]);
    }
    revolve(&profile, segments)
}

/// The surface swept by `profile` (radius, height) turning about +Y in `segments` steps; its
/// end points lie on the axis and become poles. Scaled into the unit sphere.
fn revolve(profile: &[[f64; 2]], segments: usize) -> Mesh {
    let rings = profile.len() - 2;
    let mut positions = vec![[0.0, profile[0][1], 0.0]];
    for p in &profile[1..=rings] {
        for s in 0..segments {
            let a = std::f64::consts::TAU * s as f64 / segments as f64;
            positions.push([p[0] * a.cos(), p[1], p[0] * a.sin()]);
        }
    }
    let last = positions.len() as u32;
    positions.push([0.0, profile[profile.len() - 1][1], 0.0]);
    let ring = |r: usize, s: usize| (1 + r * segments + s % segments) as u32;
    let mut faces = Vec::new();
    for s in 0..segments {
        faces.push([0, ring(0, s + 1), ring(0, s)]);
        for r in 0..rings - 1 {
            let (a, b, c, d) = (ring(r, s), ring(r, s + 1), ring(r + 1, s + 1), ring(r + 1, s));
            faces.extend([[a, b, c], [a, c, d]]);
        }
        faces.push([last, ring(rings - 1, s), ring(rings - 1, s + 1)]);
    }
    unit_sphere_mesh(positions, faces)
}

/// A mesh of `positions` and `faces`, centred on its bounding box and scaled so that its
/// farthest vertex is at distance 1; normals from the faces.
fn unit_sphere_mesh(positions: Vec<[f64; 3]>, faces: Vec<[u32; 3]>) -> Mesh {
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for p in &positions {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let centre = [0, 1, 2].map(|k| (lo[k] + hi[k]) / 2.0);
    let radius = positions
        .iter()
        .map(|p| ((p[0] - centre[0]).powi(2) + (p[1] - centre[1]).powi(2) + (p[2] - centre[2]).powi(2)).sqrt())
        .fold(0.0, f64::max);
    let positions = positions.iter().map(|p| [0, 1, 2].map(|k| ((p[k] - centre[k]) / radius) as f32)).collect();
    Mesh { positions, normals: None, faces, vertex_properties: Vec::new() }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    /// Closed and consistently oriented outwards: after welding equal positions, every directed
    /// edge has exactly one reverse, and the enclosed volume is positive.
    fn assert_closed_outward(name: &str, mesh: &Mesh) {
        let mut ids: HashMap<[i64; 3], u32> = HashMap::new();
        let weld: Vec<u32> = mesh
            .positions
            .iter()
            .map(|p| {
                let key = p.map(|v| (v as f64 * 1e5).round() as i64);
                let next = ids.len() as u32;
                *ids.entry(key).or_insert(next)
            })
            .collect();
        let mut edges: HashMap<(u32, u32), i32> = HashMap::new();
        let mut volume = 0.0;
        for f in &mesh.faces {
            let [a, b, c] = f.map(|i| weld[i as usize]);
            for (u, v) in [(a, b), (b, c), (c, a)] {
                *edges.entry((u, v)).or_default() += 1;
            }
            let [p, q, r] = f.map(|i| mesh.positions[i as usize].map(|v| v as f64));
            volume += (p[0] * (q[1] * r[2] - q[2] * r[1]) - p[1] * (q[0] * r[2] - q[2] * r[0])
                + p[2] * (q[0] * r[1] - q[1] * r[0]))
                / 6.0;
        }
        for (&(u, v), &count) in &edges {
            assert_eq!((count, edges.get(&(v, u))), (1, Some(&1)), "{name}: edge {u}-{v}");
        }
        assert!(volume > 0.05, "{name}: volume {volume}");
        assert!((mesh.radius() - 1.0).abs() < 1e-4, "{name}: radius {}", mesh.radius());
    }

    #[test]
    fn procedural_shapes_are_closed_outward_and_in_the_unit_sphere() {
        assert_closed_outward("bumpy sphere", &bumpy_sphere(3, 8, 0.05, 1));
        assert_closed_outward("torus knot", &torus_knot(2, 3, 0.3, 128, 12));
        assert_closed_outward("gear", &gear(12, 0.75, 0.5));
        assert_closed_outward("bowl", &bowl(0.6, 0.15, 64));
        assert_closed_outward("torus", &torus(0.4, 64, 16));
    }
}
