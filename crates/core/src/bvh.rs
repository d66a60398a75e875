//! A bounding volume hierarchy over the scene's triangles and the patches'
//! squares (two triangles each, tagged with their patch), for the
//! visibility rays of the form-factor stage (`radiosity_bake::form_factor`).
//!
//! **Build** (host, f64 decisions on f32 data, deterministic): binned
//! surface-area-heuristic splits (Wald, "On fast Construction of SAH-based
//! Bounding Volume Hierarchies", 2007) with [`BINS`] bins per axis, leaves of
//! at most [`MAX_LEAF`] triangles unless the centroids coincide, and an
//! object-median split below depth [`SAH_DEPTH`] so the depth (and the
//! kernel's traversal stack) stays bounded. No randomness and no parallel
//! reduction: the same triangles give the same bytes.
//!
//! **Layout** (shared with `crates/bake/kernels/form_factor.cl`): [`Node`]s of 8 words
//! (box min, left child or first triangle, box max, triangle count; a count
//! of 0 marks an inner node whose children are `left` and `left + 1`),
//! triangles in leaf order as [`Tri`] (three vertices and the triangle's
//! facing [`Direction`]), and one [`Cert`] per triangle (see below). All
//! coordinates are f32 relative to a shift point (the grid's centre) so
//! their rounding error is relative to the scene's half extent.
//!
//! **Queries**: [`Bvh::any_hit`] finds any triangle crossing a segment,
//! skipping hits a filter rejects, in f64 on the f32 data: it is the CPU
//! reference of the kernel's `any_hit`. The triangle test is Möller–Trumbore
//! ("Fast, Minimum Storage Ray/Triangle Intersection", 1997) with the
//! barycentric range widened by [`EDGE_EPS`] so that a ray through the
//! shared edge of two triangles cannot slip between them under rounding
//! (the test is not watertight otherwise); the cost is an over-occlusion of
//! 1e-5 of a triangle's size at silhouette edges.
//!
//! **Occlusion certificates**: [`Cert`] stores, per triangle, the largest
//! convex planar polygon it belongs to: the triangle itself, or the convex
//! quadrilateral it forms with a coplanar neighbour sharing an edge (a wall
//! made of two triangles). A segment whose crossing with that polygon's
//! plane lies strictly inside it is blocked by one of the two triangles; the
//! form-factor stage uses that to prove a whole pair of patches blocked
//! after one ray. A patch square's own certificate is the square; the
//! form-factor stage replaces it by the certificate of the scene polygon
//! the square lies on, when there is one (any real blocking polygon is a
//! valid certificate, whichever triangle the ray hit).

use crate::math::{cross, dot, f64s, sub};
use crate::patch::Direction;
use std::collections::HashMap;
use std::time::Instant;

/// [`Tri::patch`] of a scene triangle.
pub const SCENE: u32 = u32::MAX;

/// An extra convex quad occluder (a patch's square): corners
/// counter-clockwise around `direction`'s side, world coordinates.
#[derive(Clone, Copy, Debug)]
pub struct Square {
    pub corners: [[f64; 3]; 4],
    pub direction: Direction,
}

/// How far behind a point's tangent plane (as the cosine with the normal) a
/// segment may leave or reach it in [`Bvh::surface_segment_clear`]: a 24-gon
/// column's adjacent facets meet at 15°, a chord between them dips 7.5°
/// behind each (cosine 0.13).
pub const SIDE_SLACK: f64 = 0.25;

/// Bins per axis of the SAH sweep.
pub const BINS: usize = 16;
/// Most triangles in a leaf (more only when their centroids coincide).
pub const MAX_LEAF: usize = 4;
/// Below this depth the build splits at the object median instead of by
/// SAH, which bounds the depth by `SAH_DEPTH + log2(triangles)`.
pub const SAH_DEPTH: usize = 36;
/// Size of the traversal stack in the kernel and the reference (the depth
/// bound above plus one, with margin).
pub const STACK: usize = 64;
/// Widening of the barycentric range of the triangle test (see the module
/// doc). Equals `EDGE_EPS` in the kernel.
pub const EDGE_EPS: f64 = 1e-5;

/// A node: box and either two children (`count == 0`: children `left` and
/// `left + 1`) or `count` triangles from `left`. 32 bytes, as in the kernel.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Node {
    pub min: [f32; 3],
    pub left: u32,
    pub max: [f32; 3],
    pub count: u32,
}

/// A triangle in leaf order: vertices relative to the shift point, the
/// facing direction of its geometric normal ([`Direction`] as `u32`), and
/// the patch whose square it is half of ([`SCENE`] for scene triangles).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Tri {
    pub v0: [f32; 3],
    pub dir: u32,
    pub v1: [f32; 3],
    pub patch: u32,
    pub v2: [f32; 3],
    pub pad2: u32,
}

/// The convex planar polygon (3 or 4 vertices, counter-clockwise around
/// `normal`) that a triangle belongs to, for occlusion certificates.
/// `meta` holds the vertex count (low byte) and the facing direction the
/// form-factor stage's own-box rule compares (second byte; [`NO_DIR`] for
/// a patch square).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Cert {
    pub v: [[f32; 3]; 4],
    pub normal: [f32; 3],
    pub meta: u32,
}

/// The direction value of a certificate that no patch direction matches.
pub const NO_DIR: u32 = 6;

impl Cert {
    /// Number of vertices (3 or 4).
    pub fn count(&self) -> usize {
        (self.meta & 0xff) as usize
    }
    /// The direction the own-box rule compares.
    pub fn dir(&self) -> u32 {
        self.meta >> 8
    }
    fn meta(count: u32, dir: u32) -> u32 {
        count | dir << 8
    }
}

/// Counts and time of one build.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct BvhStats {
    /// Scene triangles, and patch squares (two triangles each).
    pub triangles: u64,
    pub squares: u64,
    pub nodes: u64,
    pub leaves: u64,
    pub max_depth: u64,
    pub max_leaf: u64,
    /// Triangles whose certificate polygon is a quadrilateral (merged with a
    /// coplanar neighbour).
    pub quad_certificates: u64,
    /// Patch squares given the certificate of the scene polygon they lie
    /// on (set by the form-factor stage).
    pub squares_on_scene_polygons: u64,
    pub seconds: f64,
}

/// The hierarchy, ready to upload or to query on the CPU.
#[derive(Clone, Debug)]
pub struct Bvh {
    pub nodes: Vec<Node>,
    /// Triangles in leaf order.
    pub tris: Vec<Tri>,
    /// Certificates in leaf order.
    pub certs: Vec<Cert>,
    /// The primitive of each leaf-order triangle: a scene triangle index,
    /// or `triangles + 2 k (+ 1)` for the halves of square `k`.
    pub order: Vec<u32>,
    /// World position subtracted from every coordinate.
    pub shift: [f64; 3],
    pub stats: BvhStats,
}

#[derive(Clone, Copy)]
struct Aabb {
    lo: [f32; 3],
    hi: [f32; 3],
}

impl Aabb {
    const EMPTY: Aabb = Aabb {
        lo: [f32::INFINITY; 3],
        hi: [f32::NEG_INFINITY; 3],
    };
    fn grow(&mut self, o: &Aabb) {
        for k in 0..3 {
            self.lo[k] = self.lo[k].min(o.lo[k]);
            self.hi[k] = self.hi[k].max(o.hi[k]);
        }
    }
    fn area(&self) -> f64 {
        if self.lo[0] > self.hi[0] {
            return 0.0;
        }
        let e: [f64; 3] = std::array::from_fn(|k| self.hi[k] as f64 - self.lo[k] as f64);
        2.0 * (e[0] * e[1] + e[1] * e[2] + e[2] * e[0])
    }
}

impl Bvh {
    /// Builds the hierarchy over `triangles` (indices into `positions`,
    /// world coordinates), storing coordinates relative to `shift`.
    pub fn build(positions: &[[f32; 3]], triangles: &[[u32; 3]], shift: [f64; 3]) -> Bvh {
        Self::build_with_squares(positions, triangles, &[], shift)
    }

    /// [`Bvh::build`] plus `squares` (two triangles each, with patch index
    /// = position in `squares`, facing their given direction, and the
    /// square itself as certificate).
    pub fn build_with_squares(
        positions: &[[f32; 3]],
        triangles: &[[u32; 3]],
        squares: &[Square],
        shift: [f64; 3],
    ) -> Bvh {
        let start = Instant::now();
        let local =
            |p: [f32; 3]| -> [f32; 3] { std::array::from_fn(|k| (p[k] as f64 - shift[k]) as f32) };
        let local64 =
            |p: [f64; 3]| -> [f32; 3] { std::array::from_fn(|k| (p[k] - shift[k]) as f32) };
        let mut verts: Vec<[[f32; 3]; 3]> = triangles
            .iter()
            .map(|t| t.map(|v| local(positions[v as usize])))
            .collect();
        for sq in squares {
            let c = sq.corners.map(local64);
            verts.push([c[0], c[1], c[2]]);
            verts.push([c[0], c[2], c[3]]);
        }
        let boxes: Vec<Aabb> = verts
            .iter()
            .map(|v| {
                let mut b = Aabb::EMPTY;
                for p in v {
                    b.grow(&Aabb { lo: *p, hi: *p });
                }
                b
            })
            .collect();
        let centroids: Vec<[f32; 3]> = boxes
            .iter()
            .map(|b| std::array::from_fn(|k| 0.5 * (b.lo[k] + b.hi[k])))
            .collect();
        let mut index: Vec<u32> = (0..verts.len() as u32).collect();
        let mut nodes = vec![Node::default()];
        let mut stats = BvhStats {
            triangles: triangles.len() as u64,
            squares: squares.len() as u64,
            ..Default::default()
        };
        // (node, first, end, depth)
        let mut work = vec![(0usize, 0usize, verts.len(), 0usize)];
        while let Some((node, first, end, depth)) = work.pop() {
            let mut bounds = Aabb::EMPTY;
            let mut cbounds = Aabb::EMPTY;
            for &t in &index[first..end] {
                bounds.grow(&boxes[t as usize]);
                let c = centroids[t as usize];
                cbounds.grow(&Aabb { lo: c, hi: c });
            }
            nodes[node].min = bounds.lo;
            nodes[node].max = bounds.hi;
            stats.max_depth = stats.max_depth.max(depth as u64);
            let count = end - first;
            let make_leaf = |nodes: &mut Vec<Node>, stats: &mut BvhStats| {
                nodes[node].left = first as u32;
                nodes[node].count = count as u32;
                stats.leaves += 1;
                stats.max_leaf = stats.max_leaf.max(count as u64);
            };
            let extent: [f32; 3] = std::array::from_fn(|k| cbounds.hi[k] - cbounds.lo[k]);
            let axis_max = if extent[0] >= extent[1] && extent[0] >= extent[2] {
                0
            } else if extent[1] >= extent[2] {
                1
            } else {
                2
            };
            if count <= 1 || extent[axis_max] <= 0.0 {
                make_leaf(&mut nodes, &mut stats);
                continue;
            }
            let mid = if depth < SAH_DEPTH {
                // Binned SAH: cost = A_L N_L + A_R N_R (relative to the
                // parent, with traversal and intersection costs equal).
                let mut best: Option<(f64, usize, usize)> = None;
                for axis in 0..3 {
                    if extent[axis] <= 0.0 {
                        continue;
                    }
                    let scale = BINS as f64 / extent[axis] as f64;
                    let bin_of = |t: u32| -> usize {
                        let c = centroids[t as usize][axis] as f64 - cbounds.lo[axis] as f64;
                        ((c * scale) as usize).min(BINS - 1)
                    };
                    let mut bin_box = [Aabb::EMPTY; BINS];
                    let mut bin_n = [0usize; BINS];
                    for &t in &index[first..end] {
                        let b = bin_of(t);
                        bin_box[b].grow(&boxes[t as usize]);
                        bin_n[b] += 1;
                    }
                    let mut right_area = [0.0f64; BINS];
                    let mut acc = Aabb::EMPTY;
                    for b in (1..BINS).rev() {
                        acc.grow(&bin_box[b]);
                        right_area[b] = acc.area();
                    }
                    let mut acc = Aabb::EMPTY;
                    let mut n_left = 0usize;
                    for split in 1..BINS {
                        acc.grow(&bin_box[split - 1]);
                        n_left += bin_n[split - 1];
                        let n_right = count - n_left;
                        if n_left == 0 || n_right == 0 {
                            continue;
                        }
                        let cost = acc.area() * n_left as f64 + right_area[split] * n_right as f64;
                        if best.is_none_or(|(c, _, _)| cost < c) {
                            best = Some((cost, axis, split));
                        }
                    }
                }
                let leaf_cost = bounds.area() * count as f64;
                match best {
                    Some((cost, axis, split)) => {
                        if count <= MAX_LEAF && cost >= leaf_cost {
                            make_leaf(&mut nodes, &mut stats);
                            continue;
                        }
                        let scale = BINS as f64 / extent[axis] as f64;
                        let slice = &mut index[first..end];
                        let mut l = 0;
                        for r in 0..slice.len() {
                            let c =
                                centroids[slice[r] as usize][axis] as f64 - cbounds.lo[axis] as f64;
                            if (((c * scale) as usize).min(BINS - 1)) < split {
                                slice.swap(l, r);
                                l += 1;
                            }
                        }
                        first + l
                    }
                    None => median(&mut index[first..end], &centroids, axis_max) + first,
                }
            } else {
                median(&mut index[first..end], &centroids, axis_max) + first
            };
            let left = nodes.len();
            nodes.push(Node::default());
            nodes.push(Node::default());
            nodes[node].left = left as u32;
            nodes[node].count = 0;
            work.push((left + 1, mid, end, depth + 1));
            work.push((left, first, mid, depth + 1));
        }
        // Widen every box a little so that the f32 slab test stays
        // conservative for triangles lying in a box face.
        for n in &mut nodes {
            for k in 0..3 {
                let pad = (n.max[k] - n.min[k]) * 1e-5 + (n.min[k].abs() + n.max[k].abs()) * 1e-6;
                n.min[k] -= pad;
                n.max[k] += pad;
            }
        }
        // The pads are rounded to f32 and depend on each box's own bounds,
        // so a child's padded box can stick out of its parent's by an ulp.
        // Grow parents to hold their children (children come after their
        // parent), so that a box's slab test passing implies its
        // ancestors' pass: what `hits_in_leaf` and the four-wide traversal
        // (`core::bvh4`) rely on.
        for i in (0..nodes.len()).rev() {
            if nodes[i].count == 0 {
                let l = nodes[i].left as usize;
                for k in 0..3 {
                    let lo = nodes[l].min[k].min(nodes[l + 1].min[k]);
                    let hi = nodes[l].max[k].max(nodes[l + 1].max[k]);
                    nodes[i].min[k] = nodes[i].min[k].min(lo);
                    nodes[i].max[k] = nodes[i].max[k].max(hi);
                }
            }
        }
        let mut certs_all = certificates(positions, triangles, shift, &mut stats);
        for sq in squares {
            let c = sq.corners.map(local64);
            let n = sq.direction.vector();
            let e = [
                sub(sq.corners[1], sq.corners[0]),
                sub(sq.corners[2], sq.corners[1]),
            ];
            let nn = cross(e[0], e[1]);
            let len = dot(nn, nn).sqrt();
            let normal = if len > 0.0 {
                nn.map(|x| (x / len) as f32)
            } else {
                n.map(|x| x as f32)
            };
            let cert = Cert {
                v: c,
                normal,
                meta: Cert::meta(4, NO_DIR),
            };
            certs_all.push(cert);
            certs_all.push(cert);
        }
        let nt = triangles.len();
        let tris = index
            .iter()
            .map(|&t| {
                let v = verts[t as usize];
                let (dir, patch) = if (t as usize) < nt {
                    let n = cross(sub(f64s(v[1]), f64s(v[0])), sub(f64s(v[2]), f64s(v[0])));
                    (Direction::dominant(n) as u32, SCENE)
                } else {
                    let k = (t as usize - nt) / 2;
                    (squares[k].direction as u32, k as u32)
                };
                Tri {
                    v0: v[0],
                    dir,
                    v1: v[1],
                    patch,
                    v2: v[2],
                    pad2: 0,
                }
            })
            .collect();
        let certs = index.iter().map(|&t| certs_all[t as usize]).collect();
        stats.nodes = nodes.len() as u64;
        stats.seconds = start.elapsed().as_secs_f64();
        Bvh {
            nodes,
            tris,
            certs,
            order: index,
            shift,
            stats,
        }
    }

    /// Any triangle crossing the segment `o + t d`, `t ∈ [0, 1]`, that
    /// `ignore(leaf_index, t)` does not reject: its leaf-order index, or
    /// `None`. Mirrors `any_hit` in the kernel (same traversal order), in
    /// f64.
    pub fn any_hit(
        &self,
        o: [f64; 3],
        d: [f64; 3],
        ignore: impl FnMut(u32, f64) -> bool,
    ) -> Option<u32> {
        self.any_hit_leaf(o, d, ignore).map(|(_, k)| k)
    }

    /// [`Bvh::any_hit`], also returning the leaf node that holds the
    /// triangle, for [`Bvh::hits_in_leaf`].
    pub fn any_hit_leaf(
        &self,
        o: [f64; 3],
        d: [f64; 3],
        mut ignore: impl FnMut(u32, f64) -> bool,
    ) -> Option<(u32, u32)> {
        if self.tris.is_empty() {
            return None;
        }
        let inv = d.map(|x| 1.0 / x);
        let mut stack = [0u32; STACK];
        let mut sp = 0usize;
        let mut node = 0u32;
        slab(&self.nodes[0], o, inv)?;
        loop {
            let n = &self.nodes[node as usize];
            if n.count > 0 {
                for k in n.left..n.left + n.count {
                    if let Some(t) = intersect(&self.tris[k as usize], o, d) {
                        if !ignore(k, t) {
                            return Some((node, k));
                        }
                    }
                }
            } else {
                let (a, b) = (n.left, n.left + 1);
                let ta = slab(&self.nodes[a as usize], o, inv);
                let tb = slab(&self.nodes[b as usize], o, inv);
                match (ta, tb) {
                    (Some(x), Some(y)) => {
                        // Nearer child first; the other waits on the stack.
                        let (near, far) = if y < x { (b, a) } else { (a, b) };
                        assert!(sp < STACK, "BVH traversal stack overflow");
                        stack[sp] = far;
                        sp += 1;
                        node = near;
                        continue;
                    }
                    (Some(_), None) => {
                        node = a;
                        continue;
                    }
                    (None, Some(_)) => {
                        node = b;
                        continue;
                    }
                    (None, None) => {}
                }
            }
            if sp == 0 {
                return None;
            }
            sp -= 1;
            node = stack[sp];
        }
    }
}

impl Bvh {
    /// Whether triangle `k` of leaf node `leaf` (as [`Bvh::any_hit_leaf`]
    /// returned them) crosses the segment `o + t d`, `t ∈ [0, 1]`, with the
    /// leaf's box crossed too: exactly when [`Bvh::any_hit`] without a
    /// filter would reach that triangle. The segment crosses every
    /// ancestor's box then, since the boxes contain the leaf's and the slab
    /// test is monotonic in the bounds, even rounded; so a `true` here
    /// means `any_hit` returns some hit. A shadow ray can test the last
    /// occluder of a neighbouring ray first (`core::direct`).
    pub fn hits_in_leaf(&self, leaf: u32, k: u32, o: [f64; 3], d: [f64; 3]) -> bool {
        let inv = d.map(|x| 1.0 / x);
        slab(&self.nodes[leaf as usize], o, inv).is_some()
            && intersect(&self.tris[k as usize], o, d).is_some()
    }

    /// Keeps in `best` the nearer of it and the triangles of the leaf `n`
    /// crossing the segment `o + t d` at `t ∈ (0, 1]` (the first met on a
    /// tie): the leaf step of both nearest-hit traversals.
    pub fn nearest_in_leaf(
        &self,
        n: &Node,
        o: [f64; 3],
        d: [f64; 3],
        best: &mut Option<(u32, f64)>,
    ) {
        for k in n.left..n.left + n.count {
            if let Some(t) = intersect(&self.tris[k as usize], o, d) {
                if t > 0.0 && best.is_none_or(|(_, bt)| t < bt) {
                    *best = Some((k, t));
                }
            }
        }
    }

    /// The nearest triangle crossing the segment `o + t d`, `t ∈ (0, 1]`:
    /// its leaf-order index and `t`; `None` when none does. Children are
    /// visited nearer first and a subtree is skipped once its box lies
    /// beyond the nearest hit so far (the run time's primary rays).
    pub fn closest_hit(&self, o: [f64; 3], d: [f64; 3]) -> Option<(u32, f64)> {
        if self.tris.is_empty() {
            return None;
        }
        let inv = d.map(|x| 1.0 / x);
        let mut best: Option<(u32, f64)> = None;
        let mut stack = [(0u32, 0.0f64); STACK];
        let mut sp = 0usize;
        let t0 = slab(&self.nodes[0], o, inv)?;
        stack[0] = (0, t0);
        sp += 1;
        while sp > 0 {
            sp -= 1;
            let (node, entry) = stack[sp];
            if best.is_some_and(|(_, bt)| entry > bt) {
                continue;
            }
            let n = &self.nodes[node as usize];
            if n.count > 0 {
                self.nearest_in_leaf(n, o, d, &mut best);
                continue;
            }
            let (a, b) = (n.left, n.left + 1);
            let ta = slab(&self.nodes[a as usize], o, inv);
            let tb = slab(&self.nodes[b as usize], o, inv);
            // Push the farther first so the nearer is popped first.
            let mut push = |c: u32, t: Option<f64>| {
                if let Some(t) = t {
                    assert!(sp < STACK, "BVH traversal stack overflow");
                    stack[sp] = (c, t);
                    sp += 1;
                }
            };
            match (ta, tb) {
                (Some(x), Some(y)) if y < x => {
                    push(a, ta);
                    push(b, tb);
                }
                _ => {
                    push(b, tb);
                    push(a, ta);
                }
            }
        }
        best
    }
}

/// What [`Bvh::surface_segment_blocker`] found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Blocker {
    /// Nothing: the two points are connected.
    Clear,
    /// The segment leaves or reaches a point behind its surface.
    Side,
    /// This scene triangle crosses the segment.
    Triangle(u32),
}

impl Bvh {
    /// Whether two points on surfaces, `a` and `b` (world coordinates,
    /// unit normals `na`, `nb`), lie on one connected stretch of surface
    /// that nothing separates: the segment between them leaves `a` and
    /// reaches `b` on their front sides (within [`SIDE_SLACK`] of the
    /// tangent plane, so gently convex surfaces pass: a chord dips just
    /// behind them), and, with each end lifted `lift` along its normal, it
    /// crosses no triangle — ignoring hits on triangles facing `dir` (a
    /// [`Direction`] as `u32`) within `own` of either end: the surfaces the
    /// points lie on, which can curve across the chord. A wall between
    /// them, of any thickness and however close to an end, blocks, and a
    /// surface reached from behind (the floor above a floor) is not
    /// connected.
    #[allow(clippy::too_many_arguments)]
    pub fn surface_segment_clear(
        &self,
        a: [f64; 3],
        na: [f64; 3],
        b: [f64; 3],
        nb: [f64; 3],
        lift: f64,
        own: f64,
        dir: u32,
    ) -> bool {
        self.surface_segment_blocker(a, na, b, nb, lift, own, dir) == Blocker::Clear
    }

    /// What keeps [`Bvh::surface_segment_clear`] from holding: nothing,
    /// the side test, or a triangle crossing the segment (its index in the
    /// scene's triangle list).
    #[allow(clippy::too_many_arguments)]
    pub fn surface_segment_blocker(
        &self,
        a: [f64; 3],
        na: [f64; 3],
        b: [f64; 3],
        nb: [f64; 3],
        lift: f64,
        own: f64,
        dir: u32,
    ) -> Blocker {
        let lifted = |p: [f64; 3], n: [f64; 3]| -> [f64; 3] {
            std::array::from_fn(|k| p[k] + lift * n[k] - self.shift[k])
        };
        let (o, e) = (lifted(a, na), lifted(b, nb));
        let d = sub(e, o);
        let len = dot(d, d).sqrt();
        if !(len > 0.0) {
            return Blocker::Clear;
        }
        if dot(d, na) < -SIDE_SLACK * len || dot(d, nb) > SIDE_SLACK * len {
            return Blocker::Side;
        }
        match self.any_hit(o, d, |k, t| {
            let (s, e) = (t * len, (1.0 - t) * len);
            self.tris[k as usize].dir == dir && (s <= own || e <= own)
        }) {
            None => Blocker::Clear,
            Some(k) => Blocker::Triangle(self.order[k as usize]),
        }
    }
}

/// Object-median split along `axis`: index of the first right element.
fn median(slice: &mut [u32], centroids: &[[f32; 3]], axis: usize) -> usize {
    let mid = slice.len() / 2;
    slice.select_nth_unstable_by(mid, |&a, &b| {
        centroids[a as usize][axis]
            .total_cmp(&centroids[b as usize][axis])
            .then(a.cmp(&b))
    });
    mid
}

/// Entry parameter of the segment `o + t d`, `t ∈ [0, 1]`, into a node's box,
/// or `None` when it misses. `min`/`max` ignore the NaN of `0 · ∞` (a
/// segment parallel to and inside a slab), as `fmin`/`fmax` do in the kernel.
/// `inv` is `1 / d` per axis.
pub fn slab(n: &Node, o: [f64; 3], inv: [f64; 3]) -> Option<f64> {
    slab_bounds(n.min.map(f64::from), n.max.map(f64::from), o, inv)
}

/// [`slab`] of the box `[lo, hi]` given in f64 (a node's f32 bounds
/// widened exactly give [`slab`]'s answer).
#[inline]
pub fn slab_bounds(lo: [f64; 3], hi: [f64; 3], o: [f64; 3], inv: [f64; 3]) -> Option<f64> {
    let mut t0 = 0.0f64;
    let mut t1 = 1.0f64;
    for k in 0..3 {
        let a = (lo[k] - o[k]) * inv[k];
        let b = (hi[k] - o[k]) * inv[k];
        t0 = t0.max(a.min(b));
        t1 = t1.min(a.max(b));
    }
    (t0 <= t1).then_some(t0)
}

/// Möller–Trumbore with the barycentric range widened by [`EDGE_EPS`]; the
/// segment parameter of the hit in `[0, 1]`, as `intersect` in the kernel.
pub fn intersect(tri: &Tri, o: [f64; 3], d: [f64; 3]) -> Option<f64> {
    let v0 = f64s(tri.v0);
    let e1 = sub(f64s(tri.v1), v0);
    let e2 = sub(f64s(tri.v2), v0);
    let p = cross(d, e2);
    let det = dot(e1, p);
    if det == 0.0 {
        return None;
    }
    let inv = 1.0 / det;
    let s = sub(o, v0);
    let u = dot(s, p) * inv;
    if !(-EDGE_EPS..=1.0 + EDGE_EPS).contains(&u) {
        return None;
    }
    let q = cross(s, e1);
    let v = dot(d, q) * inv;
    if v < -EDGE_EPS || u + v > 1.0 + EDGE_EPS {
        return None;
    }
    let t = dot(e2, q) * inv;
    (0.0..=1.0).contains(&t).then_some(t)
}

/// The certificate polygon of every scene triangle (scene order): the
/// largest convex quadrilateral it forms with a coplanar, equally oriented
/// neighbour sharing an edge (matched by exact vertex positions, so split
/// vertices with different texture coordinates still match), else itself.
fn certificates(
    positions: &[[f32; 3]],
    triangles: &[[u32; 3]],
    shift: [f64; 3],
    stats: &mut BvhStats,
) -> Vec<Cert> {
    let key = |v: u32| positions[v as usize].map(f32::to_bits);
    let mut edges: HashMap<([u32; 3], [u32; 3]), Vec<u32>> = HashMap::new();
    for (t, tri) in triangles.iter().enumerate() {
        for e in 0..3 {
            let (a, b) = (key(tri[e]), key(tri[(e + 1) % 3]));
            let k = if a <= b { (a, b) } else { (b, a) };
            edges.entry(k).or_default().push(t as u32);
        }
    }
    let world = |v: u32| f64s(positions[v as usize]);
    let unit = |n: [f64; 3]| {
        let l = dot(n, n).sqrt();
        if l > 0.0 {
            n.map(|x| x / l)
        } else {
            n
        }
    };
    let local = |p: [f64; 3]| -> [f32; 3] { std::array::from_fn(|k| (p[k] - shift[k]) as f32) };
    triangles
        .iter()
        .enumerate()
        .map(|(t, tri)| {
            let p = tri.map(world);
            let n = unit(cross(sub(p[1], p[0]), sub(p[2], p[0])));
            let size = dot(sub(p[1], p[0]), sub(p[1], p[0]))
                .max(dot(sub(p[2], p[0]), sub(p[2], p[0])))
                .sqrt();
            let mut best: Option<([[f64; 3]; 4], f64)> = None;
            for e in 0..3 {
                let (a, b, c) = (p[e], p[(e + 1) % 3], p[(e + 2) % 3]);
                let (ka, kb) = (key(tri[e]), key(tri[(e + 1) % 3]));
                let k = if ka <= kb { (ka, kb) } else { (kb, ka) };
                for &t2 in &edges[&k] {
                    if t2 as usize == t {
                        continue;
                    }
                    let q = triangles[t2 as usize].map(world);
                    let n2 = unit(cross(sub(q[1], q[0]), sub(q[2], q[0])));
                    // The neighbour's vertex off the shared edge.
                    let Some(&w) = triangles[t2 as usize]
                        .iter()
                        .find(|&&v| key(v) != ka && key(v) != kb)
                    else {
                        continue;
                    };
                    let w = world(w);
                    if dot(n, n2) < 1.0 - 1e-9 || dot(n, sub(w, a)).abs() > 1e-7 * size {
                        continue;
                    }
                    // Counter-clockwise quad a, w, b, c must be strictly convex.
                    let quad = [a, w, b, c];
                    let convex = (0..4).all(|i| {
                        let (x, y, z) = (quad[i], quad[(i + 1) % 4], quad[(i + 2) % 4]);
                        dot(cross(sub(y, x), sub(z, y)), n) > 1e-12 * size * size
                    });
                    if !convex {
                        continue;
                    }
                    let area = 0.5 * dot(cross(sub(b, a), sub(c, a)), n)
                        + 0.5 * dot(cross(sub(w, a), sub(b, a)), n);
                    if best.is_none_or(|(_, ba)| area > ba) {
                        best = Some((quad, area));
                    }
                }
            }
            let dir = Direction::dominant(n) as u32;
            match best {
                Some((quad, _)) => {
                    stats.quad_certificates += 1;
                    Cert {
                        v: quad.map(local),
                        normal: n.map(|x| x as f32),
                        meta: Cert::meta(4, dir),
                    }
                }
                None => Cert {
                    v: [local(p[0]), local(p[1]), local(p[2]), local(p[2])],
                    normal: n.map(|x| x as f32),
                    meta: Cert::meta(3, dir),
                },
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Brute force against the hierarchy on a few hundred random triangles.
    #[test]
    fn any_hit_matches_brute_force() {
        let mut s = 12345u64;
        let mut rnd = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((s >> 11) as f64 / (1u64 << 53) as f64) as f32
        };
        let mut positions = Vec::new();
        let mut triangles = Vec::new();
        for t in 0..300u32 {
            let c = [rnd() * 10.0, rnd() * 10.0, rnd() * 10.0];
            for _ in 0..3 {
                positions.push([c[0] + rnd() - 0.5, c[1] + rnd() - 0.5, c[2] + rnd() - 0.5]);
            }
            triangles.push([3 * t, 3 * t + 1, 3 * t + 2]);
        }
        let bvh = Bvh::build(&positions, &triangles, [5.0, 5.0, 5.0]);
        assert!(bvh.stats.max_depth < (STACK - 1) as u64);
        for _ in 0..2000 {
            let o = [
                rnd() as f64 * 10.0 - 5.0,
                rnd() as f64 * 10.0 - 5.0,
                rnd() as f64 * 10.0 - 5.0,
            ];
            let d = [
                rnd() as f64 * 6.0 - 3.0,
                rnd() as f64 * 6.0 - 3.0,
                rnd() as f64 * 6.0 - 3.0,
            ];
            let brute = bvh.tris.iter().any(|t| intersect(t, o, d).is_some());
            assert_eq!(bvh.any_hit(o, d, |_, _| false).is_some(), brute);
        }
    }

    /// `hits_in_leaf` never claims a hit that `any_hit` would not find:
    /// the last blocker tried on the next ray (as the direct pass does),
    /// and on the ray itself.
    #[test]
    fn a_hit_in_a_cached_leaf_is_a_hit_of_the_traversal() {
        let mut rng = crate::math::SplitMix64::new(777);
        let mut rnd = || rng.uniform();
        // A grid of unit squares (two triangles each) at y = 1: shared
        // edges, where the widened triangle test reaches past a leaf.
        let mut positions = Vec::new();
        let mut triangles = Vec::new();
        for i in 0..12u32 {
            for j in 0..12u32 {
                let b = positions.len() as u32;
                let (x, z) = (i as f32, j as f32);
                positions.extend([
                    [x, 1.0, z],
                    [x + 1.0, 1.0, z],
                    [x + 1.0, 1.0, z + 1.0],
                    [x, 1.0, z + 1.0],
                ]);
                triangles.extend([[b, b + 1, b + 2], [b, b + 2, b + 3]]);
            }
        }
        let bvh = Bvh::build(&positions, &triangles, [0.0; 3]);
        let (mut reused, mut tried) = (0, 0);
        let mut last = None;
        for _ in 0..20_000 {
            // Origins anywhere below the grid, directions upwards.
            let o = [12.0 * rnd(), 0.5 * rnd(), 12.0 * rnd()];
            let d = [rnd() - 0.5, 1.0 + rnd(), rnd() - 0.5];
            let hit = bvh.any_hit_leaf(o, d, |_, _| false);
            if let Some((leaf, k)) = last {
                tried += 1;
                if bvh.hits_in_leaf(leaf, k, o, d) {
                    reused += 1;
                    assert!(
                        hit.is_some(),
                        "cached leaf {leaf}, triangle {k}: a hit the traversal misses"
                    );
                }
            }
            if let Some((leaf, k)) = hit {
                assert!(bvh.hits_in_leaf(leaf, k, o, d), "a ray's own hit");
                last = hit;
            }
        }
        assert!(
            reused > 0 && reused < tried,
            "{reused} of {tried}: the check saw both cases"
        );
    }
}
