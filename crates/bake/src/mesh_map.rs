//! The mesh-to-patch map (docs/design.md section 1, bake step 7): for every
//! vertex of the original mesh, up to four patches and weights (≥ 0,
//! summing to 1) from which the run time interpolates the vertex's indirect
//! irradiance `H` (run-time step 4).
//!
//! The thesis picked four patches from the 27-voxel neighbourhood by normal
//! agreement alone, so a vertex on one side of a wall thinner than a voxel
//! could take light from the other side. Here a patch is *acceptable* for a
//! vertex at `p` with unit normal `n` when all of these hold (`s` is the
//! voxel size):
//!
//! 1. **It is near**: its centre lies in the vertex's voxel or one of the 26
//!    around it (patches are indexed by the voxel holding their centre).
//! 2. **It faces the same way**: `n · N ≥` [`COS_MIN`] = 0.5 (60°). This
//!    excludes the patches of a perpendicular surface meeting the vertex's
//!    at a crease (cos 0), and it lies below 1/√3 ≈ 0.577, the smallest
//!    possible largest component of a unit vector, so even a vertex whose
//!    normal runs along a cube diagonal accepts axis-aligned patches of each
//!    of the three directions it leans toward.
//! 3. **They are in front of each other**: the vertex is not behind the
//!    patch's plane, `(p − c) · N ≥ −`[`PLANE_EPS`]` · s`, and the centre is
//!    not behind the vertex's tangent plane, `(c − p) · n ≥ −PLANE_EPS · s`.
//!    The slack allows for the patch's plane being a mean plane: a curved
//!    surface deviates from it by its sagitta, a fraction of a voxel.
//! 4. **Nothing lies between them**: the segment from `p + δ n` to
//!    `c + δ N` (`δ =` [`RAY_OFFSET`]` · s`) crosses no triangle of the
//!    original scene (the BVH of [`radiosity_core::bvh`], exact f64 segment tests).
//!    This is what keeps light from leaking through thin walls: the walls are
//!    in the original triangles even where the voxel grid cannot resolve
//!    them. It is chosen over a test against other patches' planes because
//!    patches of a wall thinner than a voxel sit in the same voxel and their
//!    planes do not say where the wall ends; the triangles do. Hits that do
//!    not separate the two are ignored: within `2δ` of either end (the
//!    surface the vertex or the patch lies on), on a triangle facing the
//!    vertex's axis direction within [`OWN_SURFACE`]` · s` of the vertex (its
//!    own, possibly curved, surface), or on a triangle facing the patch's
//!    direction within `√3 · s` of its centre (the geometry the patch was
//!    made from, which a mean plane can cut). A wall between them shows a
//!    face of another direction and blocks.
//!
//! **Weights.** Each acceptable patch `j` gets the kernel weight
//! `ω_j = A_j (n · N_j) / (d_j² + (`[`KERNEL_EPS`]` · s)²)`: interpolation
//! as the quadrature of `∫ H(y) K(|x − y|) dy / ∫ K` over the surface with
//! the patches as quadrature cells (area), inverse-square distance kernel
//! (Shepard) regularised so that a vertex on a patch centre gets a finite
//! weight, discounted by normal disagreement. The four largest are kept.
//! Shepard weights alone reproduce only constants: between patch centres
//! they flatten a gradient into steps, an error of order `s |∇H|`. So the
//! weights are then moved toward *linear precision*: the weights
//! `w_j = ω̂_j (1 + λ · (t_j − m))` closest to the normalised `ω̂` (in the
//! `Σ w²/ω̂` sense, by Lagrange multipliers) that sum to 1 and whose
//! weighted mean of the centres' tangent-plane offsets `t_j` is the vertex
//! itself (`m = Σ ω̂ t`, `λ = −C⁺ m` with `C` the weighted covariance of the
//! `t_j`, inverted on the directions in which the centres spread). These
//! reproduce any field linear in position exactly. Where they would go
//! negative (the vertex outside the centres' hull, at the edge of a
//! surface), the largest step from `ω̂` toward them that keeps every
//! weight ≥ 0 is taken. On a large plane, vertices inside the patch lattice
//! are then exact for linear fields and the error is confined to a
//! one-voxel strip along the edges (`tests/mesh_map.rs` measures it).
//!
//! **When nothing is acceptable** the search widens to shells of radius 2
//! and 3 voxels with the same tests ([`MeshMapStats::widened`]). If that
//! fails too, the vertex gets the single nearest patch facing its side
//! (`n · N > 0`), found by searching outward shell by shell
//! ([`MeshMapStats::fallbacks`]); never a patch facing the other way. This
//! happens to vertices whose own surface has no patch: the underside of a
//! box standing on the floor, surfaces in gaps narrower than two voxels
//! (dropped by the voxelizer as covered), surfaces merged into a parallel
//! neighbour's mean plane more than [`PLANE_EPS`] voxels away, and vertices
//! embedded in interpenetrating geometry, which see nothing
//! ([`MeshMapStats::fallbacks_blocked`]). On Sponza at 0.25 m that is 7 %
//! of the vertices but 1.3 % of the area around them: finely tessellated
//! cornices and balustrades. A vertex with no patch facing its side in the
//! whole scene gets no patch (four zero weights,
//! [`MeshMapStats::unmapped`]). [`MeshMap::outcomes`] says which vertex was
//! mapped how.
//!
//! **Vertex normals.** The file's normal when it has one (the smooth normal
//! the renderer shades with), else the area-weighted mean of the normals of
//! the triangles using that vertex index. Sides are defined by the winding
//! (patches are built from it), so a file normal pointing against the
//! winding's normal is replaced by the latter and counted. Faces that
//! cancel (a zero-thickness two-sided sheet sharing vertices) leave the
//! vertex the normal of its largest triangle, counted as ambiguous.
//!
//! The result is deterministic: each vertex is computed independently from
//! immutable data, candidates are sorted with ties broken by index, and
//! rayon's ordered collect keeps vertex order.

use crate::voxelize::Voxelization;

use crate::error::BakeError;
use radiosity_core::bvh::Bvh;
use radiosity_core::math::{add, cross, dot, norm, scale, sub, tangent_basis};
use radiosity_core::patch::Direction;
use radiosity_core::scene::Scene;
use rayon::prelude::*;
use serde::Serialize;
use std::collections::HashMap;
use std::time::Instant;

/// Patches per vertex.
pub const MAX_PATCHES: usize = 4;

/// Least cosine between a vertex normal and an acceptable patch's normal
/// (60°; see the module doc for why 0.5 < 1/√3).
pub const COS_MIN: f64 = 0.5;

/// Slack of the two plane tests, in voxel sizes: the sagitta of a surface
/// curved on the scale of a voxel. Larger values were tried on Sponza and
/// turn most fallbacks into hidden candidates instead of mapped vertices.
pub const PLANE_EPS: f64 = 0.25;

/// Regularisation length of the distance kernel, in voxel sizes: a vertex
/// on a patch centre weighs that patch `(d² + ε²)/ε²` times more than an
/// equal one at distance `d`, 17 times for a neighbour one voxel away, so
/// interpolation stays close to the nearest patch without a singularity.
pub const KERNEL_EPS: f64 = 0.25;

/// Offset of the visibility segment's ends along their normals, in voxel
/// sizes. Coordinates in the BVH are f32 relative to the grid centre, at
/// most 2048 voxels away (`voxelize::MAX_DIM / 2`), so their rounding is
/// below 2048 · 2^-24 ≈ 1.2e-4 voxels; 1e-3 is eight times that and still
/// 200 times thinner than the tests' thin wall (0.05 in 0.25 voxels).
pub const RAY_OFFSET: f64 = 1e-3;

/// Radius, in voxel sizes, within which a triangle facing the vertex's own
/// axis direction counts as the vertex's own surface and does not block.
pub const OWN_SURFACE: f64 = 0.5;

/// Widest shell (Chebyshev radius in voxels) searched with the full tests.
pub const WIDEN_RADIUS: i64 = 3;

/// Acceptable candidates whose visibility is tested at most, in decreasing
/// weight, to find the [`MAX_PATCHES`] kept (the 27-voxel block rarely
/// holds more than about 20 patches facing one way).
pub const MAX_VISIBILITY_TESTS: usize = 24;

/// The fallback search goes shell by shell up to this radius, then scans
/// every patch.
pub const FALLBACK_SHELLS: i64 = 8;

/// Options of [`build_with`].
#[derive(Clone, Copy, Debug, Serialize)]
pub struct MeshMapOptions {
    /// Test visibility against the original triangles (criterion 4 of the
    /// module doc). Off only to measure what it prevents.
    pub visibility: bool,
    /// Move the kernel weights toward linear precision (module doc). Off
    /// only to measure what it gains over plain Shepard weights.
    pub linear_precision: bool,
}

impl Default for MeshMapOptions {
    fn default() -> Self {
        MeshMapOptions {
            visibility: true,
            linear_precision: true,
        }
    }
}

/// Counts and time of one build.
#[derive(Clone, Debug, Default, Serialize)]
pub struct MeshMapStats {
    /// Mesh vertices mapped.
    pub vertices: u64,
    /// Patches that could be used (those the matrix kept).
    pub patches: u64,
    /// Mean number of candidates per vertex in its 27-voxel block passing
    /// the normal and plane tests (before visibility and the cut to 4).
    pub mean_candidates: f64,
    /// Mean number of patches used per mapped vertex.
    pub mean_patches: f64,
    /// Vertices mapped from a widened search (radius 2 or 3).
    pub widened: u64,
    /// Vertices given the nearest patch facing their side (no acceptable
    /// candidate within radius 3).
    pub fallbacks: u64,
    /// Of the fallbacks, those that had candidates passing the normal and
    /// plane tests, all hidden by the visibility test.
    pub fallbacks_blocked: u64,
    /// Vertices with no patch at all (none in the scene faces their side).
    pub unmapped: u64,
    /// Vertices whose weights reproduce linear fields exactly (the full
    /// linear-precision step was possible).
    pub linear_precision: u64,
    /// Vertex normals taken from the file, and computed from faces.
    pub normals_from_file: u64,
    pub normals_from_faces: u64,
    /// File normals pointing against their triangles' winding, replaced.
    pub file_normals_replaced: u64,
    /// Vertices whose faces' normals cancel: the largest face's normal used.
    pub ambiguous_normals: u64,
    /// Visibility segments tested.
    pub rays: u64,
    /// Wall-clock seconds: BVH build, and the whole build including it.
    pub seconds_bvh: f64,
    pub seconds: f64,
}

/// How a vertex was mapped (module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum Outcome {
    /// From acceptable patches in its 27-voxel block.
    Regular,
    /// From acceptable patches 2 or 3 voxels away.
    Widened,
    /// The nearest patch facing its side.
    Fallback,
    /// No patch faces its side.
    Unmapped,
}

/// The map: per vertex, up to [`MAX_PATCHES`] (matrix index, weight) pairs
/// in decreasing weight; unused slots are `(0, 0.0)`.
#[derive(Clone, Debug)]
pub struct MeshMap {
    pub entries: Vec<[(u32, f32); MAX_PATCHES]>,
    /// How each vertex was mapped (for reports and for visualising where
    /// the fallbacks are).
    pub outcomes: Vec<Outcome>,
    pub stats: MeshMapStats,
}

impl MeshMap {
    /// Interpolates per-patch values (in matrix order) at every vertex: the
    /// CPU reference of run-time step 4.
    pub fn interpolate(&self, values: &[[f32; 3]]) -> Vec<[f32; 3]> {
        radiosity_bakefile::baked::interpolate(&self.entries, values)
    }
}

/// Builds the map with the default options. `patch_index_of[i]` is the
/// matrix index of voxelization patch `i`, or `None` when the patch was
/// removed (it is then never used).
pub fn build(
    scene: &Scene,
    vox: &Voxelization,
    patch_index_of: &[Option<u32>],
) -> Result<MeshMap, BakeError> {
    build_with(scene, vox, patch_index_of, &MeshMapOptions::default())
}

/// One usable patch, as the search sees it.
struct Cand {
    centre: [f64; 3],
    normal: [f64; 3],
    area: f64,
    direction: Direction,
    index: u32,
}

struct VertexResult {
    row: [(u32, f32); MAX_PATCHES],
    outcome: Outcome,
    candidates: u32,
    rays: u32,
    linear: bool,
    /// Some candidate passed the cheap tests (fallbacks only).
    blocked: bool,
}

/// Everything the per-vertex search reads.
struct Ctx<'a> {
    cands: Vec<Cand>,
    by_voxel: HashMap<[i64; 3], Vec<u32>>,
    bvh: Bvh,
    origin: [f64; 3],
    size: f64,
    options: &'a MeshMapOptions,
}

/// [`build`] with options.
pub fn build_with(
    scene: &Scene,
    vox: &Voxelization,
    patch_index_of: &[Option<u32>],
    options: &MeshMapOptions,
) -> Result<MeshMap, BakeError> {
    let start = Instant::now();
    let stage_err = |detail: String| BakeError::Mismatch {
        stage: "mesh map",
        detail,
    };
    if patch_index_of.len() != vox.patches.len() {
        return Err(stage_err(format!(
            "patch_index_of has {} entries for {} patches",
            patch_index_of.len(),
            vox.patches.len()
        )));
    }
    if !scene.normals.is_empty() && scene.normals.len() != scene.positions.len() {
        return Err(stage_err(format!(
            "the scene has {} normals for {} vertices",
            scene.normals.len(),
            scene.positions.len()
        )));
    }
    if scene.positions.len() > u32::MAX as usize {
        return Err(BakeError::TooLarge {
            stage: "mesh map",
            detail: "more than 2^32 vertices".into(),
        });
    }
    let grid = vox.grid;
    let mut stats = MeshMapStats {
        vertices: scene.positions.len() as u64,
        ..Default::default()
    };

    // Usable patches, indexed by the voxel holding their centre.
    let mut cands = Vec::new();
    let mut by_voxel: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
    for (p, idx) in vox.patches.iter().zip(patch_index_of) {
        let Some(index) = *idx else { continue };
        let v = voxel_of(p.centre, grid.origin, grid.size);
        by_voxel.entry(v).or_default().push(cands.len() as u32);
        cands.push(Cand {
            centre: p.centre,
            normal: p.normal,
            area: p.area,
            direction: p.direction,
            index,
        });
    }
    stats.patches = cands.len() as u64;

    let (normals, normal_counts) = vertex_normals(scene);
    stats.normals_from_file = normal_counts[0];
    stats.normals_from_faces = normal_counts[1];
    stats.file_normals_replaced = normal_counts[2];
    stats.ambiguous_normals = normal_counts[3];

    let t = Instant::now();
    let bvh = Bvh::build(
        &scene.positions,
        &scene.triangles,
        crate::form_factor::shift_of(&grid),
    );
    stats.seconds_bvh = t.elapsed().as_secs_f64();

    let ctx = Ctx {
        cands,
        by_voxel,
        bvh,
        origin: grid.origin,
        size: grid.size,
        options,
    };
    let results: Vec<VertexResult> = (0..scene.positions.len())
        .into_par_iter()
        .map(|v| map_vertex(&ctx, scene.positions[v].map(f64::from), normals[v]))
        .collect();

    let mut entries = Vec::with_capacity(results.len());
    let mut outcomes = Vec::with_capacity(results.len());
    let (mut cand_sum, mut used_sum, mut mapped) = (0u64, 0u64, 0u64);
    for r in results {
        cand_sum += r.candidates as u64;
        stats.rays += r.rays as u64;
        match r.outcome {
            Outcome::Regular => {}
            Outcome::Widened => stats.widened += 1,
            Outcome::Fallback => {
                stats.fallbacks += 1;
                stats.fallbacks_blocked += u64::from(r.blocked);
            }
            Outcome::Unmapped => stats.unmapped += 1,
        }
        if r.outcome != Outcome::Unmapped {
            mapped += 1;
            used_sum += r.row.iter().filter(|s| s.1 > 0.0).count() as u64;
        }
        stats.linear_precision += u64::from(r.linear);
        entries.push(r.row);
        outcomes.push(r.outcome);
    }
    stats.mean_candidates = cand_sum as f64 / stats.vertices.max(1) as f64;
    stats.mean_patches = used_sum as f64 / mapped.max(1) as f64;
    stats.seconds = start.elapsed().as_secs_f64();
    Ok(MeshMap {
        entries,
        outcomes,
        stats,
    })
}

/// The voxel holding a world point.
fn voxel_of(p: [f64; 3], origin: [f64; 3], size: f64) -> [i64; 3] {
    std::array::from_fn(|k| (p[k] / size - origin[k] / size).floor() as i64)
}

/// Unit vertex normals (module doc) and the counts [from file, from faces,
/// file normals replaced, ambiguous].
fn vertex_normals(scene: &Scene) -> (Vec<[f64; 3]>, [u64; 4]) {
    let nv = scene.positions.len();
    // Σ over adjacent triangles of (twice) area × normal, total area and the
    // largest triangle's normal, per vertex index, in triangle order.
    let mut sum = vec![[0.0f64; 3]; nv];
    let mut total = vec![0.0f64; nv];
    let mut largest = vec![(0.0f64, [0.0f64; 3]); nv];
    for tri in &scene.triangles {
        let [a, b, c] = tri.map(|v| scene.positions[v as usize].map(f64::from));
        let an = cross(sub(b, a), sub(c, a));
        let len = norm(an);
        if !(len > 0.0) {
            continue;
        }
        for &v in tri {
            let v = v as usize;
            sum[v] = add(sum[v], an);
            total[v] += len;
            if len > largest[v].0 {
                largest[v] = (len, scale(an, 1.0 / len));
            }
        }
    }
    let mut counts = [0u64; 4];
    let normals = (0..nv)
        .map(|v| {
            let len = norm(sum[v]);
            // Faces that nearly cancel (|Σ A n| ≤ 1e-3 Σ A) give no direction.
            let ambiguous = !(len > 1e-3 * total[v]);
            let geometric = if ambiguous {
                largest[v].1
            } else {
                scale(sum[v], 1.0 / len)
            };
            if let Some(f) = scene.normals.get(v) {
                let f = f.map(f64::from);
                let fl = norm(f);
                if fl.is_finite() && fl > 0.0 {
                    let f = scale(f, 1.0 / fl);
                    if ambiguous || dot(f, geometric) >= 0.0 {
                        counts[0] += 1;
                        return f;
                    }
                    counts[2] += 1;
                }
            }
            counts[1] += 1;
            if ambiguous {
                counts[3] += 1;
            }
            geometric
        })
        .collect();
    (normals, counts)
}

/// Calls `f` for each voxel at Chebyshev distance exactly `r` from `c`
/// (`r = 0`: `c` itself), in a fixed order.
fn for_shell(c: [i64; 3], r: i64, mut f: impl FnMut([i64; 3])) {
    for dz in -r..=r {
        for dy in -r..=r {
            for dx in -r..=r {
                if dx.abs().max(dy.abs()).max(dz.abs()) == r {
                    f([c[0] + dx, c[1] + dy, c[2] + dz]);
                }
            }
        }
    }
}

/// Maps one vertex at `p` with unit normal `n`.
fn map_vertex(ctx: &Ctx, p: [f64; 3], n: [f64; 3]) -> VertexResult {
    let s = ctx.size;
    let home = voxel_of(p, ctx.origin, s);
    let mut rays = 0u32;
    let mut candidates = 0u32;
    let mut blocked = false;
    for (radius_lo, radius_hi, outcome) in [(0, 1, Outcome::Regular)]
        .into_iter()
        .chain((2..=WIDEN_RADIUS).map(|r| (r, r, Outcome::Widened)))
    {
        // Candidates passing the cheap tests, with their kernel weights.
        let mut found: Vec<(f64, u32)> = Vec::new();
        for r in radius_lo..=radius_hi {
            for_shell(home, r, |vx| {
                let Some(list) = ctx.by_voxel.get(&vx) else {
                    return;
                };
                for &j in list {
                    let c = &ctx.cands[j as usize];
                    let cos = dot(n, c.normal);
                    if !(cos >= COS_MIN) {
                        continue;
                    }
                    let d = sub(c.centre, p);
                    if dot(d, c.normal) > PLANE_EPS * s || dot(d, n) < -PLANE_EPS * s {
                        continue;
                    }
                    let eps = KERNEL_EPS * s;
                    let w = c.area * cos / (dot(d, d) + eps * eps);
                    found.push((w, j));
                }
            });
        }
        if outcome == Outcome::Regular {
            candidates = found.len() as u32;
        }
        blocked |= !found.is_empty();
        // Largest weight first; ties by candidate index (deterministic).
        found.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        let mut kept: Vec<(f64, u32)> = Vec::with_capacity(MAX_PATCHES);
        for &(w, j) in found.iter().take(MAX_VISIBILITY_TESTS) {
            if kept.len() == MAX_PATCHES {
                break;
            }
            if ctx.options.visibility {
                rays += 1;
                if !visible(ctx, p, n, &ctx.cands[j as usize]) {
                    continue;
                }
            }
            kept.push((w, j));
        }
        if !kept.is_empty() {
            let (row, linear) = weights(ctx, p, n, &kept);
            return VertexResult {
                row,
                outcome,
                candidates,
                rays,
                linear,
                blocked: false,
            };
        }
    }
    match nearest_same_facing(ctx, p, n, home) {
        Some(j) => {
            let mut row = [(0u32, 0.0f32); MAX_PATCHES];
            row[0] = (ctx.cands[j as usize].index, 1.0);
            VertexResult {
                row,
                outcome: Outcome::Fallback,
                candidates,
                rays,
                linear: false,
                blocked,
            }
        }
        None => VertexResult {
            row: [(0, 0.0); MAX_PATCHES],
            outcome: Outcome::Unmapped,
            candidates,
            rays,
            linear: false,
            blocked,
        },
    }
}

/// Criterion 4 of the module doc: no triangle between the vertex and the
/// patch.
fn visible(ctx: &Ctx, p: [f64; 3], n: [f64; 3], c: &Cand) -> bool {
    let s = ctx.size;
    let delta = RAY_OFFSET * s;
    let shift = ctx.bvh.shift;
    let o = sub(add(p, scale(n, delta)), shift);
    let e = sub(add(c.centre, scale(c.normal, delta)), shift);
    let d = sub(e, o);
    let len = norm(d);
    if !(len > 2.0 * delta) {
        return true;
    }
    let vertex_dir = Direction::dominant(n) as u32;
    let patch_dir = c.direction as u32;
    let own = OWN_SURFACE * s;
    let patch_reach = 3f64.sqrt() * s;
    ctx.bvh
        .any_hit(o, d, |k, t| {
            let (from_start, from_end) = (t * len, (1.0 - t) * len);
            if from_start <= 2.0 * delta || from_end <= 2.0 * delta {
                return true;
            }
            let dir = ctx.bvh.tris[k as usize].dir;
            (dir == vertex_dir && from_start <= own)
                || (dir == patch_dir && from_end <= patch_reach)
        })
        .is_none()
}

/// The weights of the kept candidates (module doc): normalised kernel
/// weights moved toward linear precision as far as non-negativity allows.
/// Returns the canonical row and whether it reproduces linear fields.
fn weights(ctx: &Ctx, p: [f64; 3], n: [f64; 3], kept: &[(f64, u32)]) -> ([(u32, f32); 4], bool) {
    let s = ctx.size;
    let total: f64 = kept.iter().map(|k| k.0).sum();
    let base: Vec<f64> = kept.iter().map(|k| k.0 / total).collect();
    // Tangent-plane offsets of the centres, in voxel units.
    let (u, w) = tangent_basis(n);
    let t: Vec<[f64; 2]> = kept
        .iter()
        .map(|&(_, j)| {
            let d = sub(ctx.cands[j as usize].centre, p);
            [dot(d, u) / s, dot(d, w) / s]
        })
        .collect();
    let mut m = [0.0; 2];
    for (b, ti) in base.iter().zip(&t) {
        m[0] += b * ti[0];
        m[1] += b * ti[1];
    }
    let mut cov = [[0.0; 2]; 2];
    for (b, ti) in base.iter().zip(&t) {
        let e = [ti[0] - m[0], ti[1] - m[1]];
        for a in 0..2 {
            for c in 0..2 {
                cov[a][c] += b * e[a] * e[c];
            }
        }
    }
    // λ = −C⁺ m on the eigen-directions of C with variance ≥ (0.03 voxel)²:
    // below that the centres do not spread in that direction (collinear) and
    // no gradient along it can be recovered.
    let (vals, vecs) = eigen_sym2(cov);
    let spread = vals[1] >= 1e-3;
    let lambda = {
        let mut l = [0.0; 2];
        for k in 0..2 {
            if vals[k] >= 1e-3 {
                let proj = (vecs[k][0] * m[0] + vecs[k][1] * m[1]) / vals[k];
                l[0] -= proj * vecs[k][0];
                l[1] -= proj * vecs[k][1];
            }
        }
        l
    };
    let linear: Vec<f64> = base
        .iter()
        .zip(&t)
        .map(|(b, ti)| b * (1.0 + lambda[0] * (ti[0] - m[0]) + lambda[1] * (ti[1] - m[1])))
        .collect();
    // Largest step in [0, 1] from `base` toward `linear` keeping all ≥ 0.
    let mut step = if ctx.options.linear_precision {
        1.0f64
    } else {
        0.0
    };
    for (b, l) in base.iter().zip(&linear) {
        if *l < 0.0 {
            step = step.min(b / (b - l));
        }
    }
    let mut ws: Vec<(f64, u32)> = base
        .iter()
        .zip(&linear)
        .zip(kept)
        .map(|((b, l), k)| ((b + step * (l - b)).max(0.0), ctx.cands[k.1 as usize].index))
        .collect();
    let sum: f64 = ws.iter().map(|x| x.0).sum();
    for x in &mut ws {
        x.0 /= sum;
    }
    ws.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    let mut row = [(0u32, 0.0f32); MAX_PATCHES];
    for (slot, &(wt, idx)) in row.iter_mut().zip(&ws) {
        let f = wt as f32;
        if f > 0.0 {
            *slot = (idx, f);
        }
    }
    // Exact for every linear field only when the centres spread in both
    // tangent directions and the full step was taken.
    (row, spread && step >= 1.0)
}

/// Eigenvalues (largest first) and unit eigenvectors of a symmetric 2×2
/// matrix. The first eigenvector is taken from the row of `A − λI` that
/// does not cancel: `(λ − d, b)` when `a ≥ d`, else `(b, λ − a)`, whose
/// large component is `|a − d|/2 + r ≥ r` either way.
fn eigen_sym2(m: [[f64; 2]; 2]) -> ([f64; 2], [[f64; 2]; 2]) {
    let (a, b, d) = (m[0][0], 0.5 * (m[0][1] + m[1][0]), m[1][1]);
    let mean = 0.5 * (a + d);
    let r = (0.25 * (a - d) * (a - d) + b * b).sqrt();
    let vals = [mean + r, mean - r];
    let v0 = if a >= d {
        [vals[0] - d, b]
    } else {
        [b, vals[0] - a]
    };
    let l = (v0[0] * v0[0] + v0[1] * v0[1]).sqrt();
    if !(l > 0.0) {
        // A multiple of the identity: every direction is an eigenvector.
        return (vals, [[1.0, 0.0], [0.0, 1.0]]);
    }
    let v0 = [v0[0] / l, v0[1] / l];
    (vals, [v0, [-v0[1], v0[0]]])
}

/// The nearest patch with `n · N > 0`, searching shells outward (a patch in
/// shell `r` is at least `(r − 1) s` away, which bounds the search) and
/// scanning all patches beyond [`FALLBACK_SHELLS`].
fn nearest_same_facing(ctx: &Ctx, p: [f64; 3], n: [f64; 3], home: [i64; 3]) -> Option<u32> {
    let s = ctx.size;
    let mut best: Option<(f64, u32)> = None;
    let consider = |j: u32, best: &mut Option<(f64, u32)>| {
        let c = &ctx.cands[j as usize];
        if !(dot(n, c.normal) > 0.0) {
            return;
        }
        let d = sub(c.centre, p);
        let d2 = dot(d, d);
        if best.is_none_or(|(bd, bj)| d2 < bd || (d2 == bd && j < bj)) {
            *best = Some((d2, j));
        }
    };
    for r in 0..=FALLBACK_SHELLS {
        for_shell(home, r, |vx| {
            if let Some(list) = ctx.by_voxel.get(&vx) {
                for &j in list {
                    consider(j, &mut best);
                }
            }
        });
        // Shell r + 1 holds nothing nearer than r · s.
        if let Some((d2, j)) = best {
            if d2 <= (r as f64 * s).powi(2) {
                return Some(j);
            }
        }
    }
    for j in 0..ctx.cands.len() as u32 {
        consider(j, &mut best);
    }
    best.map(|b| b.1)
}
