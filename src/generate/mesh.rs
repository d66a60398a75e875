//! The triangle-mesh builder shared by every scene generator.
//!
//! Positions are rounded, when a vertex is created, to the number of decimals
//! the OBJ writer prints, so the in-memory mesh is exactly the mesh a loader
//! reads back and every test about areas or orientation sees the written
//! geometry. Triangles are counter-clockwise seen from their front (the side
//! their normal points to), the convention of the OBJ format and of the
//! loader. Large surfaces are tessellated into cells no larger than
//! `max_cell`, because the renderer lights vertices: a wall made of two big
//! triangles would interpolate indirect light across metres.

use glam::DVec3;

/// A material as written to the MTL file: `Kd` (diffuse albedo, linear RGB)
/// and `Ke` (emission, linear RGB; see `scenes/README.md` for its units).
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialDef {
    /// The name used by `newmtl` and `usemtl`.
    pub name: String,
    /// Diffuse albedo, every component in [0, 1).
    pub kd: [f32; 3],
    /// Emission; zero for surfaces that do not emit.
    pub ke: [f32; 3],
}

/// A triangle mesh in the exact form it is written to the OBJ file.
#[derive(Clone, Debug, PartialEq)]
pub struct Mesh {
    /// Vertex positions, already rounded to the decimals of the OBJ file.
    pub positions: Vec<[f64; 3]>,
    /// Counter-clockwise triangles (seen from the front), indices into
    /// `positions`, in file order (grouped by material).
    pub triangles: Vec<[u32; 3]>,
    /// The material of each triangle, an index into the scene's materials.
    pub triangle_material: Vec<u32>,
}

impl Mesh {
    /// The three corners of triangle `t`.
    pub fn corners(&self, t: usize) -> [DVec3; 3] {
        let [a, b, c] = self.triangles[t];
        [
            DVec3::from_array(self.positions[a as usize]),
            DVec3::from_array(self.positions[b as usize]),
            DVec3::from_array(self.positions[c as usize]),
        ]
    }

    /// The unnormalised normal `(b − a) × (c − a)` of triangle `t`: it points
    /// to the triangle's front and its length is twice the area.
    pub fn cross(&self, t: usize) -> DVec3 {
        let [a, b, c] = self.corners(t);
        (b - a).cross(c - a)
    }

    /// The area of triangle `t`.
    pub fn area(&self, t: usize) -> f64 {
        0.5 * self.cross(t).length()
    }

    /// The unit normal of triangle `t` (towards its front).
    pub fn normal(&self, t: usize) -> DVec3 {
        self.cross(t).normalize()
    }

    /// The centroid of triangle `t`.
    pub fn centroid(&self, t: usize) -> DVec3 {
        let [a, b, c] = self.corners(t);
        (a + b + c) / 3.0
    }

    /// The total area of the triangles that use material `material`.
    pub fn material_area(&self, material: u32) -> f64 {
        (0..self.triangles.len())
            .filter(|&t| self.triangle_material[t] == material)
            .map(|t| self.area(t))
            .sum()
    }

    /// The axis-aligned bounding box `(min, max)` of all positions.
    pub fn bounds(&self) -> (DVec3, DVec3) {
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        for p in &self.positions {
            let p = DVec3::from_array(*p);
            lo = lo.min(p);
            hi = hi.max(p);
        }
        (lo, hi)
    }
}

/// Relative degeneracy threshold: twice the area divided by the squared
/// longest edge (about the smallest altitude over the longest edge). Below
/// it a triangle is a sliver that would give a meaningless normal.
pub(crate) const DEGENERATE_RATIO: f64 = 1e-6;

/// Whether a triangle is degenerate by the measure of `DEGENERATE_RATIO`.
pub(crate) fn is_degenerate(a: DVec3, b: DVec3, c: DVec3) -> bool {
    let twice_area = (b - a).cross(c - a).length();
    let longest = (b - a)
        .length_squared()
        .max((c - b).length_squared())
        .max((a - c).length_squared());
    !(longest > 0.0 && twice_area > DEGENERATE_RATIO * longest)
}

/// Face bits for box helpers: the face whose outward normal is −x, +x, ...
pub(crate) const NX: u8 = 1;
pub(crate) const PX: u8 = 2;
pub(crate) const NY: u8 = 4;
pub(crate) const PY: u8 = 8;
pub(crate) const NZ: u8 = 16;
pub(crate) const PZ: u8 = 32;
/// All six faces of a box.
pub(crate) const ALL: u8 = 63;

/// The unit vector of axis `axis` (0 = x, 1 = y, 2 = z).
pub(crate) fn unit(axis: usize) -> DVec3 {
    let mut v = DVec3::ZERO;
    v[axis] = 1.0;
    v
}

/// The two in-plane axes `(u, v)` used for a plane perpendicular to `axis`,
/// so that the local coordinates of a point are `(p[u], p[v])`: for x-planes
/// `(z, y)`, for y-planes `(x, z)`, for z-planes `(x, y)`.
pub(crate) fn plane_axes(axis: usize) -> (usize, usize) {
    match axis {
        0 => (2, 1),
        1 => (0, 2),
        _ => (0, 1),
    }
}

/// Sorted, de-duplicated breakpoints: `lo`, `hi` and every cut strictly
/// between them.
pub(crate) fn breaks(lo: f64, hi: f64, cuts: &[f64]) -> Vec<f64> {
    let mut b = vec![lo, hi];
    b.extend(
        cuts.iter()
            .copied()
            .filter(|&c| c > lo + 1e-9 && c < hi - 1e-9),
    );
    b.sort_by(f64::total_cmp);
    b.dedup_by(|x, y| (*x - *y).abs() < 1e-9);
    b
}

/// The builder: collects materials, vertices and triangles.
pub(crate) struct MeshBuilder {
    positions: Vec<[f64; 3]>,
    triangles: Vec<[u32; 3]>,
    triangle_material: Vec<u32>,
    materials: Vec<MaterialDef>,
    current: Option<u32>,
    scale: f64,
    /// The largest edge of a tessellation cell, in scene units.
    pub(crate) max_cell: f64,
    degenerate: usize,
}

impl MeshBuilder {
    /// A builder rounding positions to `decimals` decimals and tessellating
    /// surfaces into cells of at most `max_cell`.
    pub(crate) fn new(decimals: u32, max_cell: f64) -> Self {
        MeshBuilder {
            positions: Vec::new(),
            triangles: Vec::new(),
            triangle_material: Vec::new(),
            materials: Vec::new(),
            current: None,
            scale: 10f64.powi(decimals as i32),
            max_cell,
            degenerate: 0,
        }
    }

    /// Defines a material and returns its index.
    pub(crate) fn material(&mut self, name: &str, kd: [f32; 3], ke: [f32; 3]) -> u32 {
        assert!(
            self.materials.iter().all(|m| m.name != name),
            "material {name} defined twice"
        );
        self.materials.push(MaterialDef {
            name: name.to_string(),
            kd,
            ke,
        });
        (self.materials.len() - 1) as u32
    }

    /// Makes `material` the material of the triangles that follow.
    pub(crate) fn set_material(&mut self, material: u32) {
        assert!((material as usize) < self.materials.len());
        self.current = Some(material);
    }

    /// Rounds a coordinate to the written decimals (and turns −0 into 0).
    fn round(&self, x: f64) -> f64 {
        (x * self.scale).round() / self.scale + 0.0
    }

    /// Adds a vertex (rounded) and returns its index.
    pub(crate) fn vertex(&mut self, p: DVec3) -> u32 {
        let q = [self.round(p.x), self.round(p.y), self.round(p.z)];
        self.positions.push(q);
        (self.positions.len() - 1) as u32
    }

    fn pos(&self, i: u32) -> DVec3 {
        DVec3::from_array(self.positions[i as usize])
    }

    /// Adds triangle `(a, b, c)`, counter-clockwise seen from its front.
    /// Degenerate triangles are counted and make `finish` fail.
    pub(crate) fn triangle(&mut self, a: u32, b: u32, c: u32) {
        let material = self.current.expect("set_material before adding triangles");
        if is_degenerate(self.pos(a), self.pos(b), self.pos(c)) {
            self.degenerate += 1;
            return;
        }
        self.triangles.push([a, b, c]);
        self.triangle_material.push(material);
    }

    /// Adds the quad `a b c d` (in cyclic order) as two triangles, wound so
    /// that the front faces `facing`.
    pub(crate) fn quad_idx(&mut self, a: u32, b: u32, c: u32, d: u32, facing: DVec3) {
        let n = (self.pos(b) - self.pos(a)).cross(self.pos(d) - self.pos(a))
            + (self.pos(d) - self.pos(c)).cross(self.pos(b) - self.pos(c));
        if n.dot(facing) >= 0.0 {
            self.triangle(a, b, c);
            self.triangle(a, c, d);
        } else {
            self.triangle(a, d, c);
            self.triangle(a, c, b);
        }
    }

    /// Adds a triangle wound so that its front faces `facing`.
    pub(crate) fn triangle_facing(&mut self, a: u32, b: u32, c: u32, facing: DVec3) {
        let n = (self.pos(b) - self.pos(a)).cross(self.pos(c) - self.pos(a));
        if n.dot(facing) >= 0.0 {
            self.triangle(a, b, c);
        } else {
            self.triangle(a, c, b);
        }
    }

    /// Number of segments needed to keep pieces of `length` at most `max_cell`.
    pub(crate) fn segments(&self, length: f64) -> usize {
        ((length / self.max_cell) - 1e-9).ceil().max(1.0) as usize
    }

    /// Breakpoints refined so that no interval exceeds `max_cell`.
    pub(crate) fn refine(&self, b: &[f64]) -> Vec<f64> {
        let mut out = vec![b[0]];
        for w in b.windows(2) {
            let n = self.segments(w[1] - w[0]);
            for k in 1..n {
                out.push(w[0] + (w[1] - w[0]) * k as f64 / n as f64);
            }
            out.push(w[1]);
        }
        out
    }

    /// Tessellates a planar region: the points `origin + a·u + b·v` with `a`
    /// between the first and last of `a_breaks` and `b` likewise. The
    /// breakpoints are refined to cells of at most `max_cell`; a cell is
    /// kept when `keep(a, b)` holds at its centre, so holes and cut-outs are
    /// given as breakpoints plus a predicate. Vertices are shared inside
    /// the region (no T-junctions in it) and the front faces `facing`.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn grid(
        &mut self,
        origin: DVec3,
        u: DVec3,
        v: DVec3,
        a_breaks: &[f64],
        b_breaks: &[f64],
        facing: DVec3,
        keep: &dyn Fn(f64, f64) -> bool,
    ) {
        let a = self.refine(a_breaks);
        let b = self.refine(b_breaks);
        let (na, nb) = (a.len(), b.len());
        let mut index = vec![u32::MAX; na * nb];
        for j in 0..nb - 1 {
            for i in 0..na - 1 {
                if !keep(0.5 * (a[i] + a[i + 1]), 0.5 * (b[j] + b[j + 1])) {
                    continue;
                }
                let mut id = [0u32; 4];
                for (k, (ii, jj)) in [(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)]
                    .into_iter()
                    .enumerate()
                {
                    let slot = &mut index[jj * na + ii];
                    if *slot == u32::MAX {
                        let p = origin + u * a[ii] + v * b[jj];
                        *slot = self.vertex(p);
                    }
                    id[k] = index[jj * na + ii];
                }
                self.quad_idx(id[0], id[1], id[2], id[3], facing);
            }
        }
    }

    /// An axis-aligned rectangle in the plane `p[axis] = at`, facing
    /// `sign · axis` (`sign` is ±1), spanning `a` and `b` in the plane's
    /// local coordinates (see `plane_axes`), with extra breakpoints and a
    /// keep predicate as in `grid`.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn plane_region(
        &mut self,
        axis: usize,
        at: f64,
        sign: f64,
        a: (f64, f64),
        b: (f64, f64),
        cuts_a: &[f64],
        cuts_b: &[f64],
        keep: &dyn Fn(f64, f64) -> bool,
    ) {
        let (ua, va) = plane_axes(axis);
        let origin = unit(axis) * at;
        let ab = breaks(a.0, a.1, cuts_a);
        let bb = breaks(b.0, b.1, cuts_b);
        self.grid(
            origin,
            unit(ua),
            unit(va),
            &ab,
            &bb,
            unit(axis) * sign,
            keep,
        );
    }

    /// A full axis-aligned rectangle (see `plane_region`).
    pub(crate) fn plane_rect(
        &mut self,
        axis: usize,
        at: f64,
        sign: f64,
        a: (f64, f64),
        b: (f64, f64),
    ) {
        self.plane_region(axis, at, sign, a, b, &[], &[], &|_, _| true);
    }

    /// An axis-aligned rectangle with rectangular holes `[a0, a1, b0, b1]`
    /// (local coordinates as in `plane_region`).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn plane_with_holes(
        &mut self,
        axis: usize,
        at: f64,
        sign: f64,
        a: (f64, f64),
        b: (f64, f64),
        holes: &[[f64; 4]],
    ) {
        let cuts_a: Vec<f64> = holes.iter().flat_map(|h| [h[0], h[1]]).collect();
        let cuts_b: Vec<f64> = holes.iter().flat_map(|h| [h[2], h[3]]).collect();
        let keep = |x: f64, y: f64| {
            !holes
                .iter()
                .any(|h| x > h[0] && x < h[1] && y > h[2] && y < h[3])
        };
        self.plane_region(axis, at, sign, a, b, &cuts_a, &cuts_b, &keep);
    }

    /// The faces of the axis-aligned box `[lo, hi]` selected by `mask`
    /// (`NX | PX | ...`), all facing outwards, each tessellated.
    pub(crate) fn axis_box(&mut self, lo: DVec3, hi: DVec3, mask: u8) {
        for axis in 0..3 {
            let (ua, va) = plane_axes(axis);
            let a = (lo[ua], hi[ua]);
            let b = (lo[va], hi[va]);
            if mask & (1 << (2 * axis)) != 0 {
                self.plane_rect(axis, lo[axis], -1.0, a, b);
            }
            if mask & (1 << (2 * axis + 1)) != 0 {
                self.plane_rect(axis, hi[axis], 1.0, a, b);
            }
        }
    }

    /// A quadrilateral patch with corners `c` in cyclic order, tessellated
    /// bilinearly into cells of at most `max_cell` and facing `facing`. The
    /// corners are kept exactly; a non-planar quad becomes a bilinear
    /// surface of nearly planar cells.
    pub(crate) fn quad(&mut self, c: [DVec3; 4], facing: DVec3) {
        let nu = self.segments((c[1] - c[0]).length().max((c[2] - c[3]).length()));
        let nv = self.segments((c[3] - c[0]).length().max((c[2] - c[1]).length()));
        self.patch(c, nu, nv, facing);
    }

    /// A bilinear patch with `nu × nv` cells (see `quad`).
    pub(crate) fn patch(&mut self, c: [DVec3; 4], nu: usize, nv: usize, facing: DVec3) {
        let mut index = Vec::with_capacity((nu + 1) * (nv + 1));
        for j in 0..=nv {
            for i in 0..=nu {
                let p = match (i, j) {
                    (0, 0) => c[0],
                    (i, 0) if i == nu => c[1],
                    (i, j) if i == nu && j == nv => c[2],
                    (0, j) if j == nv => c[3],
                    _ => {
                        let s = i as f64 / nu as f64;
                        let t = j as f64 / nv as f64;
                        c[0] * ((1.0 - s) * (1.0 - t))
                            + c[1] * (s * (1.0 - t))
                            + c[2] * (s * t)
                            + c[3] * ((1.0 - s) * t)
                    }
                };
                index.push(self.vertex(p));
            }
        }
        let w = nu + 1;
        for j in 0..nv {
            for i in 0..nu {
                self.quad_idx(
                    index[j * w + i],
                    index[j * w + i + 1],
                    index[(j + 1) * w + i + 1],
                    index[(j + 1) * w + i],
                    facing,
                );
            }
        }
    }

    /// The faces of the oriented box with centre `c` and half-axis vectors
    /// `h` (mutually perpendicular) selected by `mask` (bit `2k` is the face
    /// towards `−h[k]`, bit `2k + 1` towards `+h[k]`), facing outwards.
    pub(crate) fn oriented_box(&mut self, c: DVec3, h: [DVec3; 3], mask: u8) {
        for k in 0..3 {
            let (i, j) = ((k + 1) % 3, (k + 2) % 3);
            for (bit, s) in [(2 * k, -1.0), (2 * k + 1, 1.0)] {
                if mask & (1 << bit) == 0 {
                    continue;
                }
                let f = c + h[k] * s;
                let corners = [
                    f - h[i] - h[j],
                    f + h[i] - h[j],
                    f + h[i] + h[j],
                    f - h[i] + h[j],
                ];
                self.quad(corners, h[k] * s);
            }
        }
    }

    /// The side of a vertical cylinder (axis +y) standing on `base`, with
    /// `segments` facets around and rings at most `max_cell` apart, facing
    /// outwards; plus the bottom and top caps (disks) when asked.
    pub(crate) fn cylinder(
        &mut self,
        base: DVec3,
        radius: f64,
        height: f64,
        segments: usize,
        caps: (bool, bool),
    ) {
        let rings = self.segments(height);
        let dir = |k: usize| {
            let t = std::f64::consts::TAU * k as f64 / segments as f64;
            DVec3::new(t.cos(), 0.0, t.sin())
        };
        let mut index = Vec::with_capacity(segments * (rings + 1));
        for j in 0..=rings {
            let y = height * j as f64 / rings as f64;
            for k in 0..segments {
                index.push(self.vertex(base + dir(k) * radius + DVec3::Y * y));
            }
        }
        for j in 0..rings {
            for k in 0..segments {
                let k1 = (k + 1) % segments;
                let mid = dir(k) + dir(k1);
                self.quad_idx(
                    index[j * segments + k],
                    index[j * segments + k1],
                    index[(j + 1) * segments + k1],
                    index[(j + 1) * segments + k],
                    mid,
                );
            }
        }
        if caps.0 {
            self.disk(base, DVec3::X, DVec3::Z, radius, segments, -DVec3::Y);
        }
        if caps.1 {
            self.disk(
                base + DVec3::Y * height,
                DVec3::X,
                DVec3::Z,
                radius,
                segments,
                DVec3::Y,
            );
        }
    }

    /// A regular `segments`-gon inscribed in the circle of `radius` around
    /// `center` in the plane spanned by the unit vectors `e1`, `e2`, as a
    /// triangle fan around its centre, facing `facing`. Its area is
    /// `segments/2 · r² · sin(2π/segments)`, slightly less than `π r²`.
    pub(crate) fn disk(
        &mut self,
        center: DVec3,
        e1: DVec3,
        e2: DVec3,
        radius: f64,
        segments: usize,
        facing: DVec3,
    ) {
        let c = self.vertex(center);
        let rim: Vec<u32> = (0..segments)
            .map(|k| {
                let t = std::f64::consts::TAU * k as f64 / segments as f64;
                self.vertex(center + (e1 * t.cos() + e2 * t.sin()) * radius)
            })
            .collect();
        for k in 0..segments {
            self.triangle_facing(c, rim[k], rim[(k + 1) % segments], facing);
        }
    }

    /// Finishes the mesh: triangles are stably grouped by material (the
    /// order of the OBJ file's `usemtl` groups). Fails with the number of
    /// degenerate triangles if any was attempted.
    pub(crate) fn finish(self) -> Result<(Mesh, Vec<MaterialDef>), usize> {
        if self.degenerate > 0 {
            return Err(self.degenerate);
        }
        let mut order: Vec<usize> = (0..self.triangles.len()).collect();
        order.sort_by_key(|&t| self.triangle_material[t]);
        let mesh = Mesh {
            positions: self.positions,
            triangles: order.iter().map(|&t| self.triangles[t]).collect(),
            triangle_material: order.iter().map(|&t| self.triangle_material[t]).collect(),
        };
        Ok((mesh, self.materials))
    }
}

/// A semicircular arch in a wall, described in the wall's own 2D
/// coordinates `(a, b)` (`a` along the wall, `b` up): the wall panel spans
/// `a0..a1` × `b0..b1`, the opening is the half disk of radius `r` centred on
/// `(ac, b0)` (`b0` is the springing line). Requires
/// `a0 < ac − r`, `ac + r < a1` and `b0 + r < b1`.
pub(crate) struct Arch {
    /// Points of the panel's outer boundary, from `(a0, b0)` up the left
    /// side, along the top and down to `(a1, b0)`.
    pub(crate) outer: Vec<(f64, f64)>,
    /// The polar angle of each outer point seen from the centre; the inner
    /// (arc) point of column `j` is at that angle on the circle.
    pub(crate) angles: Vec<f64>,
    /// The number of layers between the arc and the outer boundary.
    pub(crate) layers: usize,
    pub(crate) ac: f64,
    pub(crate) b0: f64,
    pub(crate) r: f64,
}

impl Arch {
    /// Samples the panel's boundary with pieces of at most `max_cell` and
    /// pairs every boundary point with the arc point at the same polar
    /// angle. Polar angle decreases strictly from π to 0 along the boundary
    /// (it is star-shaped around the centre), so the columns never cross.
    pub(crate) fn new(a0: f64, a1: f64, b0: f64, b1: f64, ac: f64, r: f64, max_cell: f64) -> Arch {
        assert!(a0 < ac - r && ac + r < a1 && b0 + r < b1);
        let seg = |len: f64| ((len / max_cell) - 1e-9).ceil().max(1.0) as usize;
        let (ns, nt) = (seg(b1 - b0), seg(a1 - a0));
        let mut outer = Vec::new();
        for k in 0..ns {
            outer.push((a0, b0 + (b1 - b0) * k as f64 / ns as f64));
        }
        for k in 0..nt {
            outer.push((a0 + (a1 - a0) * k as f64 / nt as f64, b1));
        }
        for k in 0..ns {
            outer.push((a1, b1 - (b1 - b0) * k as f64 / ns as f64));
        }
        outer.push((a1, b0));
        let angles: Vec<f64> = outer.iter().map(|&(a, b)| (b - b0).atan2(a - ac)).collect();
        let depth = outer
            .iter()
            .zip(&angles)
            .map(|(&(a, b), &t)| {
                let (ia, ib) = (ac + r * t.cos(), b0 + r * t.sin());
                ((a - ia).powi(2) + (b - ib).powi(2)).sqrt()
            })
            .fold(0.0, f64::max);
        Arch {
            outer,
            angles,
            layers: seg(depth),
            ac,
            b0,
            r,
        }
    }

    /// The point of column `j`, layer `k` (layer 0 on the arc, the last on
    /// the outer boundary) in wall coordinates.
    pub(crate) fn point(&self, j: usize, k: usize) -> (f64, f64) {
        let (oa, ob) = self.outer[j];
        if k == self.layers {
            return (oa, ob);
        }
        let t = self.angles[j];
        let (ia, ib) = (self.ac + self.r * t.cos(), self.b0 + self.r * t.sin());
        let s = k as f64 / self.layers as f64;
        (ia + (oa - ia) * s, ib + (ob - ib) * s)
    }
}

impl MeshBuilder {
    /// One face of an arched wall panel (see `Arch`): the wall coordinates
    /// `(a, b)` map to `origin + a·u + b·v`; the face looks along `facing`.
    pub(crate) fn arch_face(
        &mut self,
        arch: &Arch,
        origin: DVec3,
        u: DVec3,
        v: DVec3,
        facing: DVec3,
    ) {
        let m = arch.outer.len();
        let l = arch.layers;
        let mut index = Vec::with_capacity(m * (l + 1));
        for j in 0..m {
            for k in 0..=l {
                let (a, b) = arch.point(j, k);
                index.push(self.vertex(origin + u * a + v * b));
            }
        }
        for j in 0..m - 1 {
            for k in 0..l {
                let w = l + 1;
                self.quad_idx(
                    index[j * w + k],
                    index[(j + 1) * w + k],
                    index[(j + 1) * w + k + 1],
                    index[j * w + k + 1],
                    facing,
                );
            }
        }
    }

    /// The intrados (the curved underside) of an arch through a wall: the
    /// half cylinder of the arch's arc swept from `origin` along `depth`
    /// (a vector across the wall), facing the arch's axis.
    pub(crate) fn arch_intrados(
        &mut self,
        arch: &Arch,
        origin: DVec3,
        u: DVec3,
        v: DVec3,
        depth: DVec3,
    ) {
        let nd = self.segments(depth.length());
        let m = arch.angles.len();
        let arc = |j: usize| {
            let t = arch.angles[j];
            (arch.ac + arch.r * t.cos(), arch.b0 + arch.r * t.sin())
        };
        let mut index = Vec::with_capacity(m * (nd + 1));
        for j in 0..m {
            let (a, b) = arc(j);
            for k in 0..=nd {
                index.push(self.vertex(origin + u * a + v * b + depth * (k as f64 / nd as f64)));
            }
        }
        for j in 0..m - 1 {
            let t = 0.5 * (arch.angles[j] + arch.angles[j + 1]);
            let inward = -(u * t.cos() + v * t.sin());
            for k in 0..nd {
                let w = nd + 1;
                self.quad_idx(
                    index[j * w + k],
                    index[(j + 1) * w + k],
                    index[(j + 1) * w + k + 1],
                    index[j * w + k + 1],
                    inward,
                );
            }
        }
    }

    /// A straight flight of stairs with `risers` risers of height `rise` and
    /// treads of depth `run`, `width` wide. It starts at `foot` (the corner
    /// at floor level of the first riser on the side `w = 0`) and climbs
    /// along the unit vector `dir`; `side` is the unit vector across the
    /// flight. The last riser leads onto a landing that is not part of the
    /// flight. Risers face back down the flight, treads up; the side faces
    /// (profile of the solid flight down to the floor) are added for
    /// `sides.0` (at `w = 0`, facing `−side`) and `sides.1` (at
    /// `w = width`, facing `+side`).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn stairs(
        &mut self,
        foot: DVec3,
        dir: DVec3,
        side: DVec3,
        risers: usize,
        rise: f64,
        run: f64,
        width: f64,
        sides: (bool, bool),
    ) {
        for i in 0..risers {
            // Riser i + 1 at distance i·run, from height i·rise up one rise.
            let o = foot + dir * (run * i as f64);
            let y0 = rise * i as f64;
            self.grid(
                o,
                side,
                DVec3::Y,
                &[0.0, width],
                &[y0, y0 + rise],
                -dir,
                &|_, _| true,
            );
            if i + 1 < risers {
                let o = foot + DVec3::Y * (rise * (i + 1) as f64);
                let s0 = run * i as f64;
                self.grid(
                    o,
                    side,
                    dir,
                    &[0.0, width],
                    &[s0, s0 + run],
                    DVec3::Y,
                    &|_, _| true,
                );
            }
        }
        let treads = risers - 1;
        let s_breaks: Vec<f64> = (0..=treads).map(|i| run * i as f64).collect();
        let y_breaks: Vec<f64> = (0..risers).map(|i| rise * i as f64).collect();
        let keep = |s: f64, y: f64| y < rise * ((s / run).floor() + 1.0);
        for (on, w, facing) in [(sides.0, 0.0, -side), (sides.1, width, side)] {
            if on {
                self.grid(
                    foot + side * w,
                    dir,
                    DVec3::Y,
                    &s_breaks,
                    &y_breaks,
                    facing,
                    &keep,
                );
            }
        }
    }
}
