//! A bounding volume hierarchy over triangles for ray casting: binned SAH build, depth-first
//! flattened nodes, nearest-child-first traversal, Moeller-Trumbore intersection.

use crate::math::Vec3;

/// Triangles per leaf at most (smaller leaves are built when the SAH says so).
const MAX_LEAF: usize = 4;
const BINS: usize = 16;

#[derive(Clone, Copy, Debug)]
struct Node {
    /// Bounds as `[min, max]`.
    bounds: [Vec3; 2],
    /// First triangle for leaves, right child for interior nodes (left child is the next node).
    start: u32,
    /// Triangles in a leaf; 0 for interior nodes.
    count: u32,
}

#[derive(Clone, Copy, Debug)]
struct Triangle {
    v0: Vec3,
    e1: Vec3,
    e2: Vec3,
}

/// The nearest intersection of a ray with the mesh.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Distance along the (unit) ray direction.
    pub t: f32,
    /// Index of the triangle in the mesh's face list.
    pub triangle: u32,
    /// Barycentric coordinate of the triangle's second vertex.
    pub u: f32,
    /// Barycentric coordinate of the third vertex.
    pub v: f32,
}

/// A BVH over a triangle mesh.
pub struct Bvh {
    nodes: Vec<Node>,
    triangles: Vec<Triangle>,
    /// Face index of each triangle, in leaf order.
    face: Vec<u32>,
}

#[derive(Clone, Copy)]
struct Bounds {
    min: Vec3,
    max: Vec3,
}

impl Bounds {
    const EMPTY: Bounds =
        Bounds { min: Vec3::new(f32::MAX, f32::MAX, f32::MAX), max: Vec3::new(f32::MIN, f32::MIN, f32::MIN) };

    fn grow(&mut self, p: Vec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }

    fn merge(&mut self, o: &Bounds) {
        self.min = self.min.min(o.min);
        self.max = self.max.max(o.max);
    }

    fn area(&self) -> f32 {
        let d = self.max - self.min;
        if d.x < 0.0 {
            return 0.0;
        }
        2.0 * (d.x * d.y + d.y * d.z + d.z * d.x)
    }
}

impl Bvh {
    /// Build over `faces` indexing `positions`.
    pub fn new(positions: &[[f32; 3]], faces: &[[u32; 3]]) -> Self {
        let corner = |f: &[u32; 3], k: usize| Vec3::from_array(positions[f[k] as usize]);
        let mut boxes = Vec::with_capacity(faces.len());
        let mut centroids = Vec::with_capacity(faces.len());
        for f in faces {
            let mut b = Bounds::EMPTY;
            (0..3).for_each(|k| b.grow(corner(f, k)));
            centroids.push((b.min + b.max) * 0.5);
            boxes.push(b);
        }
        let mut order: Vec<u32> = (0..faces.len() as u32).collect();
        let mut nodes = Vec::with_capacity(2 * faces.len() / MAX_LEAF + 1);
        if !faces.is_empty() {
            build(&mut nodes, &mut order, 0, &boxes, &centroids);
        }
        let triangles = order
            .iter()
            .map(|&i| {
                let f = &faces[i as usize];
                let v0 = corner(f, 0);
                Triangle { v0, e1: corner(f, 1) - v0, e2: corner(f, 2) - v0 }
            })
            .collect();
        Self { nodes, triangles, face: order }
    }

    /// The nearest hit with `t_min < t < t_max` along `origin + t direction`.
    pub fn intersect(&self, origin: Vec3, direction: Vec3, t_min: f32, t_max: f32) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        let mut t_best = t_max;
        self.traverse(origin, direction, t_min, &mut t_best, |tri, t, u, v| {
            best = Some(Hit { t, triangle: tri, u, v });
            false
        });
        best
    }

    /// Whether anything lies between `t_min` and `t_max` along the ray.
    pub fn occluded(&self, origin: Vec3, direction: Vec3, t_min: f32, t_max: f32) -> bool {
        let mut hit = false;
        let mut t_best = t_max;
        self.traverse(origin, direction, t_min, &mut t_best, |_, _, _, _| {
            hit = true;
            true
        });
        hit
    }

    /// Walk the tree; `on_hit(face, t, u, v)` returns true to stop.
    fn traverse(
        &self,
        o: Vec3,
        d: Vec3,
        t_min: f32,
        t_best: &mut f32,
        mut on_hit: impl FnMut(u32, f32, f32, f32) -> bool,
    ) {
        if self.nodes.is_empty() {
            return;
        }
        let inv = Vec3::new(1.0 / d.x, 1.0 / d.y, 1.0 / d.z);
        // Plain comparisons rather than f32::min/max (which handle NaN at a cost): an infinite
        // `inv` component gives +-inf bounds, never NaN, except for a ray exactly in a slab plane,
        // where either outcome is acceptable.
        let (lo, hi) = (|a: f32, b: f32| if a < b { a } else { b }, |a: f32, b: f32| if a > b { a } else { b });
        let slab = |n: &Node, t_far: f32| -> Option<f32> {
            let (t0, t1) = ((n.bounds[0] - o), (n.bounds[1] - o));
            let (ax, bx) = (t0.x * inv.x, t1.x * inv.x);
            let (ay, by) = (t0.y * inv.y, t1.y * inv.y);
            let (az, bz) = (t0.z * inv.z, t1.z * inv.z);
            let near = hi(hi(lo(ax, bx), lo(ay, by)), hi(lo(az, bz), t_min));
            let far = lo(lo(hi(ax, bx), hi(ay, by)), lo(hi(az, bz), t_far));
            (near <= far).then_some(near)
        };
        let mut stack = [0u32; 64];
        let mut top = 0;
        let mut index = 0usize;
        if slab(&self.nodes[0], *t_best).is_none() {
            return;
        }
        loop {
            let node = &self.nodes[index];
            if node.count > 0 {
                for k in node.start..node.start + node.count {
                    let tri = &self.triangles[k as usize];
                    let p = d.cross(tri.e2);
                    let det = tri.e1.dot(p);
                    if det.abs() < 1e-12 {
                        continue;
                    }
                    let inv_det = 1.0 / det;
                    let s = o - tri.v0;
                    let u = s.dot(p) * inv_det;
                    if !(0.0..=1.0).contains(&u) {
                        continue;
                    }
                    let q = s.cross(tri.e1);
                    let v = d.dot(q) * inv_det;
                    if v < 0.0 || u + v > 1.0 {
                        continue;
                    }
                    let t = tri.e2.dot(q) * inv_det;
                    if t > t_min && t < *t_best {
                        *t_best = t;
                        if on_hit(self.face[k as usize], t, u, v) {
                            return;
                        }
                    }
                }
            } else {
                let (left, right) = (index + 1, node.start as usize);
                let (hl, hr) = (slab(&self.nodes[left], *t_best), slab(&self.nodes[right], *t_best));
                match (hl, hr) {
                    (Some(a), Some(b)) => {
                        let (near, far) = if a <= b { (left, right) } else { (right, left) };
                        stack[top] = far as u32;
                        top += 1;
                        index = near;
                        continue;
                    }
                    (Some(_), None) => {
                        index = left;
                        continue;
                    }
                    (None, Some(_)) => {
                        index = right;
                        continue;
                    }
                    (None, None) => {}
                }
            }
            // Pop the next node still in range.
            loop {
                if top == 0 {
                    return;
                }
                top -= 1;
                let candidate = stack[top] as usize;
                if slab(&self.nodes[candidate], *t_best).is_some() {
                    index = candidate;
                    break;
                }
            }
        }
    }
}

/// Build the subtree over `order[..]` (whose first element is triangle `offset` of the final
/// order) and append its nodes depth-first.
fn build(nodes: &mut Vec<Node>, order: &mut [u32], offset: usize, boxes: &[Bounds], centroids: &[Vec3]) {
    let mut bounds = Bounds::EMPTY;
    let mut centre_bounds = Bounds::EMPTY;
    for &i in order.iter() {
        bounds.merge(&boxes[i as usize]);
        centre_bounds.grow(centroids[i as usize]);
    }
    let me = nodes.len();
    nodes.push(Node { bounds: [bounds.min, bounds.max], start: offset as u32, count: order.len() as u32 });
    if order.len() <= MAX_LEAF {
        return;
    }
    // Binned SAH over the three axes.
    let mut best: Option<(f32, usize, usize)> = None; // (cost, axis, split bin)
    for axis in 0..3 {
        let (lo, hi) = (centre_bounds.min.get(axis), centre_bounds.max.get(axis));
        if hi - lo <= 1e-12 {
            continue;
        }
        let scale = BINS as f32 / (hi - lo);
        let bin_of = |i: u32| (((centroids[i as usize].get(axis) - lo) * scale) as usize).min(BINS - 1);
        let mut bin_bounds = [Bounds::EMPTY; BINS];
        let mut bin_count = [0usize; BINS];
        for &i in order.iter() {
            let b = bin_of(i);
            bin_bounds[b].merge(&boxes[i as usize]);
            bin_count[b] += 1;
        }
        let mut right_area = [0.0f32; BINS];
        let mut right_count = [0usize; BINS];
        let (mut acc, mut n) = (Bounds::EMPTY, 0);
        for b in (1..BINS).rev() {
            acc.merge(&bin_bounds[b]);
            n += bin_count[b];
            right_area[b] = acc.area();
            right_count[b] = n;
        }
        let (mut acc, mut n) = (Bounds::EMPTY, 0);
        for b in 1..BINS {
            acc.merge(&bin_bounds[b - 1]);
            n += bin_count[b - 1];
            if n == 0 || right_count[b] == 0 {
                continue;
            }
            let cost = acc.area() * n as f32 + right_area[b] * right_count[b] as f32;
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, b));
            }
        }
    }
    let split = match best {
        Some((cost, axis, bin)) if cost < bounds.area() * order.len() as f32 || order.len() > 16 => {
            let (lo, hi) = (centre_bounds.min.get(axis), centre_bounds.max.get(axis));
            let scale = BINS as f32 / (hi - lo);
            let mut left = 0;
            for k in 0..order.len() {
                let b = (((centroids[order[k] as usize].get(axis) - lo) * scale) as usize).min(BINS - 1);
                if b < bin {
                    order.swap(k, left);
                    left += 1;
                }
            }
            left
        }
        Some(_) => return, // a leaf is cheaper
        None if order.len() <= 16 => return,
        None => order.len() / 2, // all centroids coincide: split by count
    };
    nodes[me].count = 0;
    let (l, r) = order.split_at_mut(split);
    build(nodes, l, offset, boxes, centroids);
    nodes[me].start = nodes.len() as u32;
    build(nodes, r, offset + split, boxes, centroids);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    /// A random triangle soup.
    fn soup(n: usize) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
        let mut rng = Rng::for_pixel(3, 0, 0);
        let mut positions = Vec::new();
        let mut faces = Vec::new();
        for i in 0..n {
            let c = [rng.next_f32() * 4.0 - 2.0, rng.next_f32() * 4.0 - 2.0, rng.next_f32() * 4.0 - 2.0];
            for _ in 0..3 {
                positions.push([0, 1, 2].map(|k| c[k] + 0.3 * (rng.next_f32() - 0.5)));
            }
            faces.push([3 * i as u32, 3 * i as u32 + 1, 3 * i as u32 + 2]);
        }
        (positions, faces)
    }

    /// The nearest hit by testing every triangle alone.
    fn brute_force(p: &[[f32; 3]], f: &[[u32; 3]], o: Vec3, d: Vec3) -> Option<(u32, f32)> {
        f.iter()
            .enumerate()
            .filter_map(|(i, face)| Bvh::new(p, &[*face]).intersect(o, d, 0.0, f32::MAX).map(|h| (i as u32, h.t)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
    }

    #[test]
    fn matches_brute_force() {
        let (p, f) = soup(300);
        let bvh = Bvh::new(&p, &f);
        let mut rng = Rng::for_pixel(5, 0, 0);
        let mut hits = 0;
        for _ in 0..500 {
            let o = Vec3::new(rng.next_f32() * 8.0 - 4.0, rng.next_f32() * 8.0 - 4.0, -6.0);
            // Aim at one of the triangles, so that many rays hit something.
            let face = f[rng.next_u32() as usize % f.len()];
            let target =
                face.iter().fold(Vec3::default(), |acc, &i| acc + Vec3::from_array(p[i as usize])) * (1.0 / 3.0);
            let d = (target - o).normalize();
            let got = bvh.intersect(o, d, 0.0, f32::MAX).map(|h| (h.triangle, h.t));
            let want = brute_force(&p, &f, o, d);
            assert_eq!(got.map(|g| g.0), want.map(|w| w.0));
            if let (Some(g), Some(w)) = (got, want) {
                assert!((g.1 - w.1).abs() < 1e-5);
                hits += 1;
                assert!(bvh.occluded(o, d, 0.0, g.1 + 1e-3) && !bvh.occluded(o, d, 0.0, g.1 - 1e-3));
            }
        }
        assert!(hits > 100, "{hits}");
    }
}
