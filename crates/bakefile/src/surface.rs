//! The per-pixel surface map and the patches' sample points: what the run
//! time needs to light patches from their real surfaces and to carry `H`
//! from the patches to any point of the original triangles (docs/design.md run
//! time, steps 2 and 4).
//!
//! **Sample points** (`PSMP`): per patch, [`SAMPLES_PER_PATCH`] points on
//! the patch's own triangle pieces (not on its square, which can sit inside
//! relief), each with its triangle's unit normal, in a progressive order:
//! any prefix of the list is spread over the patch's region, so a run time
//! may use the first 4, 8 or 16. Direct light on a patch is the mean over
//! its points, so a patch half in shadow gets half the light.
//!
//! **Surface map** (`SMAP`): a point `x` on triangle `t` lies in voxel `v`;
//! the triangle's *piece* in `v` names the patch that stands for it (its own
//! patch, or for a piece whose group was dropped, the nearest visible patch
//! facing the same way: a substitute, counted at bake time). Pieces are
//! listed per triangle, sorted by voxel key, so the lookup is a binary
//! search. Each patch lists its eight *lattice neighbours*: the patches of
//! the same surface in the voxels around it in its plane (offsets
//! [`OFFSETS`] along the two grid axes other than its facing axis, allowing
//! one voxel of step along the facing axis for tilted or curved surfaces),
//! kept only when a segment between the two patches' sample points crosses
//! no other surface — never through a wall. `H(x)` is the bilinear blend of
//! the piece's patch and the three neighbours of the quadrant `x` lies in,
//! with weights from `x`'s position relative to the voxel centres
//! ([`crate::baked::Baked`] evaluates it on the CPU; the GL
//! shader does the same): continuous across voxel boundaries, so no voxel
//! grid shows, and exact for fields that are linear over the lattice.
//! Missing neighbours (a surface's edge, a wall) drop out and the weights
//! are renormalised.
//!
//! # Layout (little-endian)
//!
//! `SMAP`: a 48-byte header — grid origin `3 × f64`, voxel size `f64`,
//! dims `3 × u32`, triangles `u32` — then `triangles + 1` piece starts
//! (`u32`), the pieces (`m × 8` bytes: voxel `3 × u16`, flags `u16`, then
//! `m × u32` patches, [`NONE`] for no patch), per patch its voxel and facing
//! direction (`n × 4 × u16`) and its neighbours (`n × 8 × u32`).
//! Patch indices are in the file's patch order, like the mesh map.
//!
//! Then, only in a map with cut pieces (the voxelizer's "Pieces cut by a
//! wall"): their count `u32` and per cut the index of the part it belongs
//! to (`u32`, a piece flagged [`PIECE_CUT`]) and the plane `n · p = d` in
//! the voxel's coordinates (`4 × f32`). A cut piece is a chain of parts in
//! one voxel, each but the last flagged: a point of the voxel lies in the
//! first part whose plane has it on the positive side (`n · p ≥ d`), else
//! in the last.
//!
//! `PSMP`: `n × SAMPLES_PER_PATCH` records of position `3 × f32` and unit
//! normal `3 × f32`.

use crate::section_error::SectionError;
use radiosity_core::patch::{Cut, Region, MAX_CUTS};
use serde::Serialize;

/// Sample points stored per patch.
pub const SAMPLES_PER_PATCH: usize = 16;

/// "No patch" in piece and neighbour lists.
pub const NONE: u32 = u32::MAX;

/// Lattice offsets `(du, dv)` of a patch's eight neighbours, along the grid
/// axes `(a + 1) % 3` and `(a + 2) % 3` of its facing axis `a`.
pub const OFFSETS: [(i32, i32); 8] = [
    (-1, -1),
    (0, -1),
    (1, -1),
    (-1, 0),
    (1, 0),
    (-1, 1),
    (0, 1),
    (1, 1),
];

/// The slot in [`OFFSETS`] of `(du, dv)` (not both 0).
pub fn offset_slot(du: i32, dv: i32) -> usize {
    let k = ((dv + 1) * 3 + (du + 1)) as usize;
    if k > 4 {
        k - 1
    } else {
        k
    }
}

/// Piece flag: the piece's patch is a substitute (its own group was dropped
/// or its patch removed).
pub const PIECE_SUBSTITUTE: u16 = 1;

/// Piece flag: the piece is a part of a piece cut by a wall (the
/// voxelizer's "Pieces cut by a wall") with a cut of its own, in
/// [`SurfaceMap::cuts`]; the next piece, in the same voxel, is the next
/// part of the chain.
pub const PIECE_CUT: u16 = 2;

/// A triangle's piece in one voxel and the patch that lights it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize)]
pub struct MapPiece {
    pub voxel: [u16; 3],
    pub flags: u16,
    /// File-order patch index, or [`NONE`].
    pub patch: u32,
}

/// The surface map (module doc).
#[derive(Clone, Debug, PartialEq)]
pub struct SurfaceMap {
    pub origin: [f64; 3],
    pub voxel_size: f64,
    pub dims: [u32; 3],
    /// Triangle `t`'s pieces are `pieces[tri_start[t]..tri_start[t + 1]]`.
    pub tri_start: Vec<u32>,
    /// Sorted by voxel key (x fastest) within a triangle.
    pub pieces: Vec<MapPiece>,
    /// Per patch: its voxel.
    pub patch_voxel: Vec<[u16; 3]>,
    /// Per patch: its facing direction (`Direction as u8`: +x, −x, +y, −y,
    /// +z, −z); its axis is `direction / 2`.
    pub patch_direction: Vec<u8>,
    /// Per patch: its neighbours in [`OFFSETS`] order, [`NONE`] when absent.
    pub neighbours: Vec<[u32; 8]>,
    /// The cut pieces: (index of the positive half, the plane in its
    /// voxel's coordinates), sorted by piece.
    pub cuts: Vec<(u32, Cut)>,
}

/// The sample points of every patch (module doc): `SAMPLES_PER_PATCH`
/// consecutive entries per patch.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct PatchSamples {
    pub position: Vec<[f32; 3]>,
    pub normal: Vec<[f32; 3]>,
}

/// The voxel key the pieces are sorted by.
pub fn voxel_key(v: [u16; 3], dims: [u32; 3]) -> u64 {
    v[0] as u64 + dims[0] as u64 * (v[1] as u64 + dims[1] as u64 * v[2] as u64)
}

impl Default for SurfaceMap {
    /// The map of no triangle and no patch ([`SurfaceMap::without_geometry`]
    /// of 0).
    fn default() -> Self {
        SurfaceMap::without_geometry(0)
    }
}

impl SurfaceMap {
    /// A valid map for `n` patches that maps no triangle (no pieces, no
    /// neighbours, one-voxel grid): for bakes without geometry, such as
    /// synthetic matrices in tests.
    pub fn without_geometry(n: usize) -> SurfaceMap {
        SurfaceMap {
            origin: [0.0; 3],
            voxel_size: 1.0,
            dims: [1; 3],
            tri_start: vec![0],
            pieces: Vec::new(),
            patch_voxel: vec![[0; 3]; n],
            patch_direction: vec![0; n],
            neighbours: vec![[NONE; 8]; n],
            cuts: Vec::new(),
        }
    }

    /// The cut of piece `k` when it is flagged [`PIECE_CUT`].
    pub fn cut(&self, k: usize) -> Option<Cut> {
        if self.pieces[k].flags & PIECE_CUT == 0 {
            return None;
        }
        self.cuts
            .binary_search_by_key(&(k as u32), |c| c.0)
            .ok()
            .map(|j| self.cuts[j].1)
    }

    /// The region of piece `k` (empty for a whole piece): the negative
    /// sides of the cuts of the parts before it in its chain, and the
    /// positive side of its own cut.
    pub fn region(&self, k: usize) -> Region {
        let mut start = k;
        while start > 0
            && self.pieces[start - 1].flags & PIECE_CUT != 0
            && self.pieces[start - 1].voxel == self.pieces[k].voxel
        {
            start -= 1;
        }
        let mut r = Region::default();
        for j in start..k {
            if let Some(next) = self.cut(j).and_then(|c| r.with(c, false)) {
                r = next;
            }
        }
        match self.cut(k).and_then(|c| r.with(c, true)) {
            Some(next) => next,
            None => r,
        }
    }

    /// Triangles mapped.
    pub fn triangles(&self) -> usize {
        self.tri_start.len().saturating_sub(1)
    }

    /// The pieces of triangle `t`.
    pub fn pieces_of(&self, t: usize) -> &[MapPiece] {
        &self.pieces[self.tri_start[t] as usize..self.tri_start[t + 1] as usize]
    }

    /// The bytes of `SMAP` (module doc).
    pub fn to_bytes(&self) -> Vec<u8> {
        let n = self.patch_voxel.len();
        let m = self.pieces.len();
        let mut out = Vec::with_capacity(48 + 4 * self.tri_start.len() + 12 * m + 40 * n);
        for v in self.origin {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&self.voxel_size.to_le_bytes());
        for d in self.dims {
            out.extend_from_slice(&d.to_le_bytes());
        }
        out.extend_from_slice(&(self.triangles() as u32).to_le_bytes());
        for s in &self.tri_start {
            out.extend_from_slice(&s.to_le_bytes());
        }
        for p in &self.pieces {
            for c in p.voxel {
                out.extend_from_slice(&c.to_le_bytes());
            }
            out.extend_from_slice(&p.flags.to_le_bytes());
        }
        for p in &self.pieces {
            out.extend_from_slice(&p.patch.to_le_bytes());
        }
        for (v, d) in self.patch_voxel.iter().zip(&self.patch_direction) {
            for c in v {
                out.extend_from_slice(&c.to_le_bytes());
            }
            out.extend_from_slice(&(*d as u16).to_le_bytes());
        }
        for nb in &self.neighbours {
            for x in nb {
                out.extend_from_slice(&x.to_le_bytes());
            }
        }
        // The cuts, only when there are some (a file without them reads as
        // before cuts existed).
        if !self.cuts.is_empty() {
            out.extend_from_slice(&(self.cuts.len() as u32).to_le_bytes());
            for (k, c) in &self.cuts {
                out.extend_from_slice(&k.to_le_bytes());
                for v in c.n.iter().chain([&c.d]) {
                    out.extend_from_slice(&v.to_le_bytes());
                }
            }
        }
        out
    }

    /// Reads `SMAP` for a file of `n` patches; every length is checked
    /// against the bytes present before it is read, and every field is
    /// validated ([`SurfaceMap::check`]).
    pub fn from_bytes(b: &[u8], n: usize) -> Result<SurfaceMap, SectionError> {
        let mut at = 0usize;
        let mut take = |len: usize, what: &'static str| -> Result<&[u8], SectionError> {
            if b.len() - at < len {
                return Err(SectionError::Truncated {
                    what,
                    need: len as u64,
                    at: at as u64,
                    left: (b.len() - at) as u64,
                });
            }
            at += len;
            Ok(&b[at - len..at])
        };
        let f64_at =
            |s: &[u8], k: usize| f64::from_le_bytes(s[8 * k..8 * k + 8].try_into().unwrap());
        let u32_at =
            |s: &[u8], k: usize| u32::from_le_bytes(s[4 * k..4 * k + 4].try_into().unwrap());
        let u16_at =
            |s: &[u8], k: usize| u16::from_le_bytes(s[2 * k..2 * k + 2].try_into().unwrap());
        let h = take(48, "header")?;
        let origin = [f64_at(h, 0), f64_at(h, 1), f64_at(h, 2)];
        let voxel_size = f64_at(h, 3);
        let dims = [u32_at(h, 8), u32_at(h, 9), u32_at(h, 10)];
        let tris = u32_at(h, 11) as usize;
        let s = take(
            (tris + 1)
                .checked_mul(4)
                .ok_or(SectionError::Overflow("triangle"))?,
            "piece starts",
        )?;
        let tri_start: Vec<u32> = (0..=tris).map(|k| u32_at(s, k)).collect();
        let m = *tri_start.last().unwrap_or(&0) as usize;
        let pv = take(
            m.checked_mul(8).ok_or(SectionError::Overflow("piece"))?,
            "pieces",
        )?;
        let pp = take(m * 4, "piece patches")?;
        let pieces: Vec<MapPiece> = (0..m)
            .map(|k| MapPiece {
                voxel: [
                    u16_at(pv, 4 * k),
                    u16_at(pv, 4 * k + 1),
                    u16_at(pv, 4 * k + 2),
                ],
                flags: u16_at(pv, 4 * k + 3),
                patch: u32_at(pp, k),
            })
            .collect();
        let vv = take(
            n.checked_mul(8).ok_or(SectionError::Overflow("patch"))?,
            "patch voxels",
        )?;
        let patch_voxel = (0..n)
            .map(|k| {
                [
                    u16_at(vv, 4 * k),
                    u16_at(vv, 4 * k + 1),
                    u16_at(vv, 4 * k + 2),
                ]
            })
            .collect();
        let mut patch_direction = Vec::with_capacity(n);
        for k in 0..n {
            let d = u16_at(vv, 4 * k + 3);
            if d > 5 {
                return Err(SectionError::Invalid(format!(
                    "patch {k}: facing direction {d} is not one of 0..6"
                )));
            }
            patch_direction.push(d as u8);
        }
        let nb = take(n * 32, "neighbours")?;
        let neighbours = (0..n)
            .map(|k| std::array::from_fn(|s| u32_at(nb, 8 * k + s)))
            .collect();
        // Every length above was taken from `b`, so this does not overflow.
        let before_cuts = 48 + 4 * (tris + 1) + 12 * m + 40 * n;
        let mut cuts = Vec::new();
        if b.len() > before_cuts {
            let count = u32_at(take(4, "cut count")?, 0) as usize;
            let c = take(
                count.checked_mul(20).ok_or(SectionError::Overflow("cut"))?,
                "cuts",
            )?;
            let f32_at = |k: usize| f32::from_bits(u32_at(c, k));
            for k in 0..count {
                cuts.push((
                    u32_at(c, 5 * k),
                    Cut {
                        n: [f32_at(5 * k + 1), f32_at(5 * k + 2), f32_at(5 * k + 3)],
                        d: f32_at(5 * k + 4),
                    },
                ));
            }
        }
        if at != b.len() {
            return Err(SectionError::Length {
                found: b.len() as u64,
                expected: at as u64,
                layout: format!("{} trailing bytes after byte {at}", b.len() - at),
            });
        }
        let map = SurfaceMap {
            origin,
            voxel_size,
            dims,
            tri_start,
            pieces,
            patch_voxel,
            patch_direction,
            neighbours,
            cuts,
        };
        map.check(n)?;
        Ok(map)
    }

    /// Checks every field for a file of `n` patches.
    pub fn check(&self, n: usize) -> Result<(), SectionError> {
        if !(self.origin.iter().all(|o| o.is_finite())
            && self.voxel_size.is_finite()
            && self.voxel_size > 0.0)
        {
            return Err(SectionError::Invalid(format!(
                "grid origin {:?} or voxel size {} is not finite and positive",
                self.origin, self.voxel_size
            )));
        }
        if self.dims.iter().any(|&d| d == 0 || d > u16::MAX as u32) {
            return Err(SectionError::Invalid(format!(
                "grid dims {:?} out of range",
                self.dims
            )));
        }
        if self.tri_start.first().is_some_and(|&s| s != 0)
            || self.tri_start.windows(2).any(|w| w[0] > w[1])
            || self.tri_start.last().map_or(0, |&s| s as usize) != self.pieces.len()
        {
            return Err(SectionError::Invalid(
                "piece starts are not a monotone index of the pieces".into(),
            ));
        }
        let in_grid = |v: [u16; 3]| (0..3).all(|k| (v[k] as u32) < self.dims[k]);
        for t in 0..self.triangles() {
            let ps = self.pieces_of(t);
            for (k, p) in ps.iter().enumerate() {
                if !in_grid(p.voxel) {
                    return Err(SectionError::Invalid(format!(
                        "triangle {t}: piece voxel {:?} outside the grid",
                        p.voxel
                    )));
                }
                if p.patch != NONE && p.patch as usize >= n {
                    return Err(SectionError::Invalid(format!(
                        "triangle {t}: piece patch {} out of range",
                        p.patch
                    )));
                }
                if p.flags & !(PIECE_SUBSTITUTE | PIECE_CUT) != 0 {
                    return Err(SectionError::Invalid(format!(
                        "triangle {t}: unknown piece flags {:#x}",
                        p.flags
                    )));
                }
                if p.flags & PIECE_CUT != 0 && ps.get(k + 1).is_none_or(|q| q.voxel != p.voxel) {
                    return Err(SectionError::Invalid(format!(
                        "triangle {t}: cut piece in voxel {:?} without its next part",
                        p.voxel
                    )));
                }
                // Sorted by voxel; the parts of a cut piece share one.
                let in_chain = k > 0 && ps[k - 1].flags & PIECE_CUT != 0;
                if k > 0
                    && (voxel_key(ps[k - 1].voxel, self.dims) > voxel_key(p.voxel, self.dims)
                        || (ps[k - 1].voxel == p.voxel && !in_chain))
                {
                    return Err(SectionError::Invalid(format!(
                        "triangle {t}: pieces not sorted by voxel"
                    )));
                }
                if k >= MAX_CUTS
                    && ps[k - MAX_CUTS..=k]
                        .iter()
                        .all(|q| q.flags & PIECE_CUT != 0)
                {
                    return Err(SectionError::Invalid(format!(
                        "triangle {t}: a piece in voxel {:?} is cut more than {MAX_CUTS} times",
                        p.voxel
                    )));
                }
            }
        }
        let flagged = self
            .pieces
            .iter()
            .filter(|p| p.flags & PIECE_CUT != 0)
            .count();
        if flagged != self.cuts.len()
            || self.cuts.windows(2).any(|w| w[0].0 >= w[1].0)
            || self.cuts.iter().any(|(k, _)| {
                self.pieces
                    .get(*k as usize)
                    .is_none_or(|p| p.flags & PIECE_CUT == 0)
            })
        {
            return Err(SectionError::Invalid(format!(
                "{} cuts for {flagged} cut pieces, unsorted or naming a piece not cut",
                self.cuts.len()
            )));
        }
        if let Some((k, c)) = self.cuts.iter().find(|(_, c)| {
            let len = c.n.iter().map(|&x| x as f64 * x as f64).sum::<f64>().sqrt();
            !(c.d.is_finite() && len > 0.5 && len < 2.0)
        }) {
            return Err(SectionError::Invalid(format!(
                "piece {k}: cut plane n = {:?}, d = {} is not finite with a unit normal",
                c.n, c.d
            )));
        }
        if self.patch_direction.len() != n || self.patch_direction.iter().any(|&d| d > 5) {
            return Err(SectionError::Invalid(format!(
                "{} patch directions for {n} patches, or one outside 0..6",
                self.patch_direction.len()
            )));
        }
        if self.patch_voxel.len() != n || self.neighbours.len() != n {
            return Err(SectionError::Invalid(format!(
                "{} patch voxels and {} neighbour lists for {n} patches",
                self.patch_voxel.len(),
                self.neighbours.len()
            )));
        }
        if let Some(v) = self.patch_voxel.iter().find(|v| !in_grid(**v)) {
            return Err(SectionError::Invalid(format!(
                "patch voxel {v:?} outside the grid"
            )));
        }
        for (i, nb) in self.neighbours.iter().enumerate() {
            if let Some(&x) = nb
                .iter()
                .find(|&&x| x != NONE && (x as usize >= n || x as usize == i))
            {
                return Err(SectionError::Invalid(format!(
                    "patch {i}: neighbour {x} out of range or itself"
                )));
            }
        }
        Ok(())
    }

    /// The same map with patch indices renumbered by `new_of[old]` (the
    /// permutation into matrix order, applied once at load).
    pub fn renumbered(&self, order: &[u32], new_of: &[u32]) -> SurfaceMap {
        let map = |x: u32| if x == NONE { NONE } else { new_of[x as usize] };
        SurfaceMap {
            pieces: self
                .pieces
                .iter()
                .map(|p| MapPiece {
                    patch: map(p.patch),
                    ..*p
                })
                .collect(),
            patch_voxel: order
                .iter()
                .map(|&o| self.patch_voxel[o as usize])
                .collect(),
            patch_direction: order
                .iter()
                .map(|&o| self.patch_direction[o as usize])
                .collect(),
            neighbours: order
                .iter()
                .map(|&o| self.neighbours[o as usize].map(map))
                .collect(),
            ..self.clone()
        }
    }
}

impl PatchSamples {
    /// Every sample of each patch at `(centre, normal)`: for bakes without
    /// geometry, such as synthetic matrices in tests.
    pub fn at_centres(patches: &[([f32; 3], [f32; 3])]) -> PatchSamples {
        let mut s = PatchSamples::default();
        for &(c, n) in patches {
            for _ in 0..SAMPLES_PER_PATCH {
                s.position.push(c);
                s.normal.push(n);
            }
        }
        s
    }

    /// The bytes of `PSMP`.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(24 * self.position.len());
        for (p, q) in self.position.iter().zip(&self.normal) {
            for v in p.iter().chain(q) {
                out.extend_from_slice(&v.to_le_bytes());
            }
        }
        out
    }

    /// Reads `PSMP` for `n` patches, checking sizes, finiteness and unit
    /// normals (within `tolerance` of length 1).
    pub fn from_bytes(b: &[u8], n: usize, tolerance: f64) -> Result<PatchSamples, SectionError> {
        let count = n * SAMPLES_PER_PATCH;
        if b.len() != count * 24 {
            return Err(SectionError::Invalid(format!(
                "{} bytes, expected {count} samples of 24 bytes for {n} patches",
                b.len()
            )));
        }
        let f = |k: usize| f32::from_le_bytes(b[4 * k..4 * k + 4].try_into().unwrap());
        let s = PatchSamples {
            position: (0..count)
                .map(|i| std::array::from_fn(|q| f(6 * i + q)))
                .collect(),
            normal: (0..count)
                .map(|i| std::array::from_fn(|q| f(6 * i + 3 + q)))
                .collect(),
        };
        s.check(n, tolerance)?;
        Ok(s)
    }

    /// Checks sizes, finiteness and unit normals.
    pub fn check(&self, n: usize, tolerance: f64) -> Result<(), SectionError> {
        let count = n * SAMPLES_PER_PATCH;
        if self.position.len() != count || self.normal.len() != count {
            return Err(SectionError::Invalid(format!(
                "{} positions and {} normals for {n} patches ({count} expected)",
                self.position.len(),
                self.normal.len()
            )));
        }
        for (i, (p, q)) in self.position.iter().zip(&self.normal).enumerate() {
            if !p.iter().chain(q).all(|v| v.is_finite()) {
                return Err(SectionError::Invalid(format!(
                    "sample {i} is not finite: {p:?} {q:?}"
                )));
            }
            let len = q.iter().map(|&x| x as f64 * x as f64).sum::<f64>().sqrt();
            if (len - 1.0).abs() > tolerance {
                return Err(SectionError::Invalid(format!(
                    "sample {i}: normal {q:?} has length {len}, not 1"
                )));
            }
        }
        Ok(())
    }

    /// The samples in matrix order.
    pub fn reordered(&self, order: &[u32]) -> PatchSamples {
        let mut out = PatchSamples::default();
        for &o in order {
            let r = o as usize * SAMPLES_PER_PATCH..(o as usize + 1) * SAMPLES_PER_PATCH;
            out.position.extend_from_slice(&self.position[r.clone()]);
            out.normal.extend_from_slice(&self.normal[r]);
        }
        out
    }
}

/// A map for tests: one triangle whose piece in voxel (1, 0, 0) is cut
/// twice: x ≥ 0.3 (part 0, patch 0), else x ≤ 0.6 (part 1, patch 1), else
/// part 2 (patch 2); one whole piece in voxel (2, 0, 0) (patch 1).
#[doc(hidden)]
pub fn cut_chain_example() -> SurfaceMap {
    let mut m = SurfaceMap::without_geometry(3);
    m.dims = [4, 1, 1];
    m.tri_start = vec![0, 4];
    let piece = |x: u16, flags: u16, patch: u32| MapPiece {
        voxel: [x, 0, 0],
        flags,
        patch,
    };
    m.pieces = vec![
        piece(1, PIECE_CUT, 0),
        piece(1, PIECE_CUT, 1),
        piece(1, 0, 2),
        piece(2, 0, 1),
    ];
    m.cuts = vec![
        (
            0,
            Cut {
                n: [-1.0, 0.0, 0.0],
                d: -0.3,
            },
        ),
        (
            1,
            Cut {
                n: [-1.0, 0.0, 0.0],
                d: -0.6,
            },
        ),
    ];
    m.patch_voxel = vec![[1, 0, 0]; 3];
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_chain_of_cuts_round_trips_and_names_its_regions() {
        let m = cut_chain_example();
        m.check(3).unwrap();
        let b = m.to_bytes();
        assert_eq!(SurfaceMap::from_bytes(&b, 3).unwrap(), m);
        // Part 1: the negative side of cut 0 and the positive of cut 1.
        let r = m.region(1);
        assert_eq!(r.sides().len(), 2);
        assert!(r.contains([0.5, 0.5, 0.5]));
        assert!(!r.contains([0.2, 0.5, 0.5]) && !r.contains([0.7, 0.5, 0.5]));
        assert!(m.region(2).contains([0.9, 0.5, 0.5]));
        assert!(!m.region(2).contains([0.5, 0.5, 0.5]));
        assert!(m.region(3).sides().is_empty());
        // A map without cuts has no tail: its bytes are the format before
        // cuts existed, and read back.
        let mut plain = cut_chain_example();
        plain.pieces = vec![plain.pieces[2], plain.pieces[3]];
        plain.tri_start = vec![0, 2];
        plain.cuts.clear();
        let b = plain.to_bytes();
        assert_eq!(b.len(), 48 + 8 + 2 * 12 + 3 * 40);
        assert_eq!(SurfaceMap::from_bytes(&b, 3).unwrap(), plain);
    }

    #[test]
    fn broken_chains_are_refused_with_what_is_wrong() {
        let mut m = cut_chain_example();
        m.pieces[2].flags = PIECE_CUT;
        m.pieces.pop();
        m.tri_start = vec![0, 3];
        m.cuts.push((
            2,
            Cut {
                n: [1.0, 0.0, 0.0],
                d: 0.5,
            },
        ));
        let e = m.check(3).unwrap_err().to_string();
        assert!(e.contains("without its next part"), "{e}");

        let mut m = cut_chain_example();
        m.cuts.pop();
        let e = m.check(3).unwrap_err().to_string();
        assert!(e.contains("1 cuts for 2 cut pieces"), "{e}");

        let mut m = cut_chain_example();
        m.cuts[1].1.d = f32::NAN;
        let e = m.check(3).unwrap_err().to_string();
        assert!(e.contains("piece 1: cut plane"), "{e}");

        let mut m = cut_chain_example();
        m.pieces[1].flags = 0;
        let e = m.check(3).unwrap_err().to_string();
        assert!(e.contains("not sorted") || e.contains("cut pieces"), "{e}");

        // Truncated in the cut table.
        let b = cut_chain_example().to_bytes();
        let e = SurfaceMap::from_bytes(&b[..b.len() - 3], 3).unwrap_err();
        assert!(
            matches!(e, SectionError::Truncated { what: "cuts", .. }),
            "{e}"
        );
    }
}
