//! A bounding volume hierarchy over triangles for ray casting: a binary tree built with binned
//! SAH, collapsed into a 4-wide tree whose nodes test their four child boxes at once (laid out
//! as structure of arrays, so that the slab tests compile to SIMD lanes), nearest-child-first
//! traversal, Moeller-Trumbore intersection.

use crate::math::Vec3;

/// Triangles per leaf at most (smaller leaves are built when the SAH says so).
const MAX_LEAF: usize = 2;
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

/// Slot marker of a wide node without a child there.
const EMPTY: u32 = u32::MAX;

/// A node of the 4-wide tree: four child boxes and what each child is.
#[derive(Clone, Copy, Debug)]
struct WideNode {
    min: [[f32; 4]; 3],
    max: [[f32; 4]; 3],
    /// Wide-node index (inner child) or first triangle (leaf child).
    child: [u32; 4],
    /// Triangles of a leaf child, 0 for an inner child, [`EMPTY`] for no child.
    count: [u32; 4],
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
    nodes: Vec<WideNode>,
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
        let mut binary = Vec::with_capacity(2 * faces.len() / MAX_LEAF + 1);
        let mut nodes = Vec::with_capacity(faces.len() / MAX_LEAF + 1);
        if !faces.is_empty() {
            build(&mut binary, &mut order, 0, &boxes, &centroids);
            collapse(&binary, 0, &mut nodes);
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
        self.traverse::<false>(origin, direction, t_min, &mut t_best, |tri, t, u, v| {
            best = Some(Hit { t, triangle: tri, u, v });
            false
        });
        best
    }

    /// Whether anything lies between `t_min` and `t_max` along the ray.
    pub fn occluded(&self, origin: Vec3, direction: Vec3, t_min: f32, t_max: f32) -> bool {
        let mut hit = false;
        let mut t_best = t_max;
        self.traverse::<true>(origin, direction, t_min, &mut t_best, |_, _, _, _| {
            hit = true;
            true
        });
        hit
    }

    /// Walk the tree; `on_hit(face, t, u, v)` returns true to stop. `ANY_HIT` skips ordering.
    fn traverse<const ANY_HIT: bool>(
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
        let inv = [1.0 / d.x, 1.0 / d.y, 1.0 / d.z];
        let origin = [o.x, o.y, o.z];
        // Stack of (wide node, entry distance), left uninitialised: zeroing 2 KB per ray cost
        // more than a shadow ray's traversal. Entries below `top` are always written.
        let mut stack = [std::mem::MaybeUninit::<(u32, f32)>::uninit(); 256];
        stack[0].write((0, 0.0));
        let mut top = 1;
        while top > 0 {
            top -= 1;
            // SAFETY: every slot below `top` was written before `top` grew past it.
            let (index, entry) = unsafe { stack[top].assume_init() };
            if entry > *t_best {
                continue;
            }
            let node = &self.nodes[index as usize];
            // Four slab tests at once. Plain comparisons rather than f32::min/max (which pay for
            // NaN handling): an infinite `inv` gives +-inf bounds, never NaN, except for a ray
            // exactly in a slab plane, where either outcome is acceptable.
            let mut near = [t_min; 4];
            let mut far = [*t_best; 4];
            for axis in 0..3 {
                for k in 0..4 {
                    let a = (node.min[axis][k] - origin[axis]) * inv[axis];
                    let b = (node.max[axis][k] - origin[axis]) * inv[axis];
                    let (lo, hi) = if a < b { (a, b) } else { (b, a) };
                    near[k] = if lo > near[k] { lo } else { near[k] };
                    far[k] = if hi < far[k] { hi } else { far[k] };
                }
            }
            let mut inner = [(0u32, 0.0f32); 4];
            let mut inner_count = 0;
            for k in 0..4 {
                if node.count[k] == EMPTY || near[k] > far[k] {
                    continue;
                }
                if node.count[k] == 0 {
                    inner[inner_count] = (node.child[k], near[k]);
                    inner_count += 1;
                    continue;
                }
                for t_index in node.child[k]..node.child[k] + node.count[k] {
                    let tri = &self.triangles[t_index as usize];
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
                        if on_hit(self.face[t_index as usize], t, u, v) {
                            return;
                        }
                    }
                }
            }
            // Push the farthest first, so that the nearest child is visited next.
            let inner = &mut inner[..inner_count];
            if !ANY_HIT {
                // Insertion sort, farthest first: at most four entries.
                for i in 1..inner.len() {
                    let mut j = i;
                    while j > 0 && inner[j - 1].1 < inner[j].1 {
                        inner.swap(j - 1, j);
                        j -= 1;
                    }
                }
            }
            for &entry in inner.iter() {
                stack[top].write(entry);
                top += 1;
            }
        }
    }
}

/// Collapse the binary subtree at `index` (an inner node, or the root) into 4-wide nodes:
/// repeatedly open the largest inner child until four children are gathered. Returns the
/// index of the wide node.
fn collapse(binary: &[Node], index: usize, wide: &mut Vec<WideNode>) -> u32 {
    let me = wide.len();
    wide.push(WideNode { min: [[f32::MAX; 4]; 3], max: [[f32::MIN; 4]; 3], child: [0; 4], count: [EMPTY; 4] });
    let area = |k: usize| {
        let n = &binary[k];
        Bounds { min: n.bounds[0], max: n.bounds[1] }.area()
    };
    let mut kids: Vec<usize> =
        if binary[index].count > 0 { vec![index] } else { vec![index + 1, binary[index].start as usize] };
    while kids.len() < 4 {
        let largest_inner = kids
            .iter()
            .enumerate()
            .filter(|(_, &k)| binary[k].count == 0)
            .max_by(|a, b| area(*a.1).total_cmp(&area(*b.1)))
            .map(|(slot, _)| slot);
        let Some(slot) = largest_inner else { break };
        let k = kids.swap_remove(slot);
        kids.extend([k + 1, binary[k].start as usize]);
    }
    for (slot, &k) in kids.iter().enumerate() {
        let n = &binary[k];
        for axis in 0..3 {
            wide[me].min[axis][slot] = n.bounds[0].get(axis);
            wide[me].max[axis][slot] = n.bounds[1].get(axis);
        }
        let (child, count) = if n.count > 0 { (n.start, n.count) } else { (collapse(binary, k, wide), 0) };
        wide[me].child[slot] = child;
        wide[me].count[slot] = count;
    }
    me as u32
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
    use rmvp_dataset::rng::Rng;

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
