//! The contour method: each patch a square in its mean plane, Lambert's
//! exact point-to-polygon factor over Gauss–Legendre points, visibility by
//! rays against the original triangles; on OpenCL (`crates/bake/kernels/form_factor.cl`)
//! or the f64 CPU reference (`cpu.rs`). Chosen by
//! `FormFactorMethod::Contour`; the default is [`super::rays`].
//!
//! ## Patch shape
//! A patch is a centre, a unit normal and an area (see [`Patch`]). Here each
//! patch is the square of side `√A` centred at its centre in its plane, with
//! edges along the grid axes projected into that plane (`u` = the axis after
//! the patch's facing axis, made orthogonal to the normal; `v = n × u`). For
//! a patch of a surface aligned with the grid this is exactly the voxel face
//! scaled to the patch's area, and full patches of a grid-aligned plate tile
//! the plate without gap or overlap, so plate-level sums of `F` converge to
//! the plate's analytic factor. The choice is deterministic and needs
//! nothing but the patch itself.
//!
//! ## The integral
//! `A_i F_ij = ∫_{A_i} F_{dA_x→A_j} dA_x` with, for a point `x` of normal
//! `n` and a polygon of vertices `R_k` (relative to `x`), Lambert's contour
//! integral of the differential-area-to-polygon factor (Lambert,
//! *Photometria*, 1760; in the form used for radiosity by Baum, Rushmeier
//! and Winget, "Improving Radiosity Solutions Through the Use of
//! Analytically Determined Form-Factors", SIGGRAPH 1989):
//!
//! `F_{dA→A} = 1/(2π) Σ_k γ_k n · (R_k × R_{k+1}) / |R_k × R_{k+1}|`,
//! `γ_k` the angle between `R_k` and `R_{k+1}`, evaluated as
//! `atan2(|R_k × R_{k+1}|, R_k · R_{k+1})`, which stays accurate for the
//! tiny angles of distant patches (an `acos` of a cosine near 1 loses half
//! the digits).
//!
//! The outer integral over the *emitter* (the smaller patch of the pair) is
//! an `m × m` Gauss–Legendre product rule; the inner integral over the
//! receiver is exact. This is why near and adjacent patches come out right
//! where point-to-point estimates `cos θ_i cos θ_j A_j / (π r²)` fail: the
//! point-to-point kernel has a `1/r²` singularity at a shared edge and is
//! wrong by orders of magnitude once `r` is comparable to the patch size,
//! while the point-to-polygon factor is bounded (≤ 1) and smooth inside the
//! emitter (its derivative is only log-singular at a shared edge, on the
//! boundary, which Gauss nodes never touch), so a few nodes suffice. The
//! receiver polygon is first clipped to the half space above the sample
//! point's tangent plane (only that part is visible from `x`), which makes
//! perpendicular neighbours and patches that cut each other's planes exact
//! in the inner integral; a sample point behind the receiver's plane sees
//! its back and contributes 0.
//!
//! Gauss–Legendre rather than stratified midpoints: for adjacent
//! perpendicular squares the 4 × 4 midpoint rule is off by 2e-3 and the
//! 4 × 4 Gauss rule by 2e-6 (and 3 × 3 by 2e-5), at the same cost. `m`
//! adapts to the pair: the smallest rule whose error model
//! ([`QUADRATURE_ERROR`]: relative error `≤ C_m (side/distance)^(2m)`)
//! meets [`FormFactorOptions::quadrature_tol`], capped at
//! [`FormFactorOptions::samples`]; distant pairs need one node.
//!
//! ## Visibility: rays against the original triangles (and the squares)
//! Chosen over the voxel scene because the patches are an approximation of
//! the surfaces that gathers light, not a good occluder: patch squares of
//! partial voxels and curved surfaces leave gaps (light leaks) and a voxel
//! occupancy grid blocks grazing rays along every surface it contains and
//! cannot represent sub-voxel occluders partially. The triangles are exact
//! occluders and give fractional occlusion by thin and small objects; they
//! cost a BVH ([`radiosity_core::bvh`]) of the scene's triangles instead of the
//! patches' (a few more levels).
//!
//! The patch squares are occluders too (two triangles each in the same
//! BVH; a pair ignores its own two squares). The receivers are squares,
//! and where squares of different patches cover the same directions from a
//! sample point but the triangles there have a hole (a square sticks out
//! past its geometry), both receivers would count those directions: on
//! Sponza at 5.7k patches this pushed row sums to 1.68. With the squares
//! blocking, every direction reaches at most the first square it meets,
//! so row sums stay at or below 1 up to the rays' sampling of partial
//! occlusion; the cost is a little over-occlusion where squares stick out.
//!
//! Each emitter sample `x` casts `⌈rays / m²⌉` rays
//! ([`FormFactorOptions::rays`] per pair, at least one per sample) to points
//! of the receiver square (a rank-1 lattice — the R2 sequence of
//! Roberts, "The Unreasonable Effectiveness of Quasirandom Sequences", 2018
//! — with a Cranley–Patterson rotation hashed from the emitter, receiver and
//! sample indices: low-discrepancy, seeded, deterministic), skipping points
//! below `x`'s horizon. The fraction of unblocked rays multiplies that
//! sample's unoccluded Lambert factor, so partial occlusion is fractional.
//!
//! Patch sample points are not on the triangles (a patch is the mean plane
//! of the geometry in its voxel), so a ray can cross the very surface its
//! patch stands for. A hit is therefore ignored when it lies in the
//! emitter's (receiver's) *own box* — its voxel joined with its square,
//! widened by [`PLANE_TOL`] voxel edges — **and** either the triangle faces
//! the same axis direction as that patch (the geometry the patch was made
//! of, e.g. where a curved surface bulges in front of its mean plane) or
//! the hit lies within the tolerance of the patch's plane (the ray's very
//! end: this lets rays leave and reach a double-sided sheet whose two faces
//! coincide). A wall meeting a floor patch's voxel still blocks that
//! patch's rays (it faces another way and rises above the floor's plane),
//! so thin walls on voxel boundaries do not leak, and grazing rays are
//! exempt only inside the two end boxes. Other patches' squares get no
//! same-direction exemption (they are never part of `e` or `r`).
//!
//! ## Skipping what a pair does not need (each rule counted)
//! 1. **Back-facing**: if the receiver's centre lies on or behind the
//!    emitter's plane, or the emitter's centre on or behind the receiver's
//!    (both tests, with a tolerance of [`PLANE_TOL`] voxel edges for
//!    coplanar patches), the factor is 0 and nothing is cast. The test is
//!    on centres, not on whole squares, on purpose: a patch is the mean
//!    plane of the geometry in a voxel, and when each centre is behind the
//!    other's plane the two pieces of geometry face away from each other
//!    (a convex crease or box corner); their squares then only see each
//!    other through the parts that stick out past the real geometry. The
//!    corner test let the two faces of a Cornell-box block corner that
//!    share a voxel exchange F = 0.18 and pushed that row sum to 1.10.
//!    Genuine pairs keep their centres in front of each other (a concave
//!    crease rises in front of its neighbour), and planar plates at any
//!    angle are unaffected.
//! 2. **Certified blocked**: each blocked ray of a pair, until the first open
//!    one and at most [`CERT_ATTEMPTS`] times, is checked against its
//!    triangle's occlusion certificate ([`radiosity_core::bvh::Cert`]):
//!    when every segment between the emitter's sample hull and the receiver
//!    square provably crosses that convex polygon at a counted hit (both
//!    hulls strictly on opposite sides of its plane, all 16 corner-to-corner
//!    crossings strictly inside it and off both patches' planes, and the
//!    own-box rule cannot apply), the whole pair is blocked at once. A patch
//!    square's certificate is the scene polygon it lies on, when there is
//!    one (see `square_certificates`), so a ray stopped by a wall's patch
//!    square proves as much as one stopped by the wall. Pairs of different
//!    rooms behind a wall cost one ray instead of `max(rays, m²)`. The rule
//!    never changes a result: the full estimate would cast only rays inside
//!    that hull, and all of them would be blocked.
//! 3. Blocked samples skip the Lambert evaluation.
//!
//! ## Invariants (enforced, counted, reported in [`FormFactorStats`])
//! Each unordered pair is computed once, as `G_ij = A_e Σ_x w_x F_x V_x`
//! (Gauss nodes `x`, weights `w_x` summing to 1, visible fractions `V_x`)
//! with `e` the emitter, and both `F_ij = G_ij / A_i` and `F_ji = G_ij / A_j`
//! are derived from it: reciprocity holds to f32 rounding. `F_ii = 0`.
//! Negative `G` (rounding of near-zero contributions) is set to 0 and
//! counted. A row summing above `1 + ROW_SUM_TOL` (quadrature error, the
//! rays' sampling of partial occlusion, or squares of small patches at
//! junctions of curved geometry overlapping where the triangles leave a
//! hole) is rescaled to sum to 1 together
//! with its column (so reciprocity is kept), in patch order, and counted.
//! Patches whose row sums to 0 see nothing: they are removed, counted, and
//! [`FormFactors::kept`] lists the input indices kept.
//!
//! ## Determinism
//! One work-item (or one CPU task) per pair, no atomics, no reductions
//! across pairs on the device; the host sums in a fixed order. Batch sizes
//! adapt to the measured speed but a pair's result does not depend on its
//! batch. The same patches, scene and options give the same bytes.
//!
//! ## OpenCL and the CPU reference
//! `crates/bake/kernels/form_factor.cl` computes in f32 (`FP_CONTRACT OFF`); the
//! reference [`cpu_pair`] follows it step by step in f64, except for the
//! discrete decisions (back-facing, `m`, emitter choice), which it takes in
//! f32 with the kernel's exact operations so both paths evaluate the same
//! pairs the same way.

use super::cpu::cpu_pair;
use super::cpu::P64;
use super::{FormFactorOptions, FormFactorStats, FormFactors, ROW_SUM_TOL};
use crate::compute::Backend;
use crate::compute::{round_up, Access, Gpu};
use crate::error::BakeError;
use radiosity_core::bvh::{self, Bvh, Cert, Node, Square, Tri};
use radiosity_core::math::{add, cross, dot, f64s, scale, sub, unit};
use radiosity_core::patch::Grid;
use radiosity_core::patch::Patch;
use radiosity_core::patch::CORNERS;
use radiosity_core::scene::Scene;
use rayon::prelude::*;
use std::time::Instant;

/// The kernel source, embedded.
pub const KERNEL_SOURCE: &str = include_str!("../../kernels/form_factor.cl");

/// Coplanarity and certificate margin, in voxel edges: a receiver whose
/// centre lies less than this above the emitter's plane counts as
/// back-facing, own boxes are widened by it, hits this close to an end
/// patch's plane inside its box are ignored, and certificates keep this
/// distance from polygon edges and planes. It is far above the f32
/// rounding of coordinates relative to the grid centre (at most ~2048 voxel
/// edges, so ~1.2e-4 voxel edges) and equal in both paths.
pub const PLANE_TOL: f64 = 1e-3;

/// Most emitter samples per side.
pub const MAX_SAMPLES: u32 = 16;
/// Most rays per pair.
pub const MAX_RAYS: u32 = 64;

/// R2 sequence steps `2^32 / g` and `2^32 / g²`, `g` the plastic number
/// 1.32471795724474602596 (Roberts 2018), as 32-bit fixed point.
pub const R2_A1: u32 = 3242174889;
pub const R2_A2: u32 = 2447445414;

/// How a pair was handled (the top byte of the per-pair info word).
pub mod rule {
    /// Not a pair of the batch (j ≤ i).
    pub const NONE: u32 = 0;
    /// Skipped: one patch is on or behind the other's plane.
    pub const BACKFACING: u32 = 1;
    /// Skipped after one ray: an occlusion certificate proved it blocked.
    pub const BLOCKED: u32 = 2;
    /// Fully evaluated.
    pub const EVALUATED: u32 = 3;
}

/// Most occlusion-certificate checks per pair (each on a blocked ray, until
/// the first open ray): a pair blocked first by small triangles often has
/// a large one behind the next ray. Equals `CERT_ATTEMPTS` in the kernel.
pub const CERT_ATTEMPTS: u32 = 3;

/// Bytes of one [`ClPatch`].
pub const PATCH_BYTES: usize = 96;

/// A patch as the kernel reads it (`Patch` in `crates/bake/kernels/form_factor.cl`):
/// centre, half side, unit normal, area, in-plane axes, facing direction,
/// and the own box (see the module doc), all relative to the shift point.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ClPatch {
    pub c: [f32; 3],
    pub h: f32,
    pub n: [f32; 3],
    pub area: f32,
    pub u: [f32; 3],
    pub dir: u32,
    pub v: [f32; 3],
    pub pad0: f32,
    pub lo: [f32; 3],
    pub pad1: f32,
    pub hi: [f32; 3],
    pub pad2: f32,
}

/// Everything both paths read: patches in the kernel's layout, the BVH and
/// the scalar parameters, all f32 exactly as the kernel gets them.
pub struct Prepared {
    pub patches: Vec<ClPatch>,
    pub bvh: Bvh,
    /// [`PLANE_TOL`] in scene units.
    pub tol: f32,
    /// The table the kernel reads ([`rule_table`]).
    pub rules: Vec<f32>,
    pub samples: u32,
    pub rays: u32,
    pub certificates: bool,
    /// Gauss–Legendre rules for `m = 1..=samples` (f64, the reference's).
    pub gauss: Vec<Vec<(f64, f64)>>,
}

/// The shift point: the grid's centre (coordinates relative to it have the
/// smallest f32 rounding error).
pub fn shift_of(grid: &Grid) -> [f64; 3] {
    std::array::from_fn(|k| grid.origin[k] + 0.5 * grid.size * grid.dims[k] as f64)
}

/// Patches in the kernel's layout.
pub fn prepare_patches(patches: &[Patch], grid: &Grid) -> Vec<ClPatch> {
    let shift = shift_of(grid);
    let tol = PLANE_TOL * grid.size;
    let f = |x: [f64; 3]| -> [f32; 3] { x.map(|c| c as f32) };
    patches
        .iter()
        .map(|p| {
            let fr = p.frame();
            let (u, v, h) = (fr.u, fr.v, fr.half);
            let mut lo: [f64; 3] =
                std::array::from_fn(|k| grid.origin[k] + grid.size * p.voxel[k] as f64);
            let mut hi: [f64; 3] = std::array::from_fn(|k| lo[k] + grid.size);
            for (su, sv) in CORNERS {
                let q = add(p.centre, add(scale(u, su * h), scale(v, sv * h)));
                for k in 0..3 {
                    lo[k] = lo[k].min(q[k]);
                    hi[k] = hi[k].max(q[k]);
                }
            }
            ClPatch {
                c: f(sub(p.centre, shift)),
                h: h as f32,
                n: f(unit(p.normal)),
                area: p.area as f32,
                u: f(u),
                dir: p.direction as u32,
                v: f(v),
                pad0: 0.0,
                lo: f(std::array::from_fn(|k| lo[k] - tol - shift[k])),
                pad1: 0.0,
                hi: f(std::array::from_fn(|k| hi[k] + tol - shift[k])),
                pad2: 0.0,
            }
        })
        .collect()
}

/// Prepares both paths' inputs: patches, the BVH of the scene's triangles.
pub fn prepare(
    scene: &Scene,
    patches: &[Patch],
    grid: &Grid,
    options: &FormFactorOptions,
) -> Result<Prepared, BakeError> {
    options.validate()?;
    if patches.len() > u32::MAX as usize / 2 {
        return Err(BakeError::TooLarge {
            stage: "form factors",
            detail: format!("{} patches are too many", patches.len()),
        });
    }
    for (i, p) in patches.iter().enumerate() {
        let finite = p.centre.iter().chain(&p.normal).all(|x| x.is_finite()) && p.area.is_finite();
        if !finite || !(p.area > 0.0) || !(dot(p.normal, p.normal) > 0.0) {
            return Err(BakeError::Numeric {
                stage: "form factors",
                detail: format!(
                    "patch {i} is degenerate: centre {:?}, normal {:?}, area {}",
                    p.centre, p.normal, p.area
                ),
            });
        }
    }
    let squares: Vec<Square> = patches
        .iter()
        .map(|p| {
            let fr = p.frame();
            let (u, v, h) = (fr.u, fr.v, fr.half);
            // Counter-clockwise around the normal (u × v = n).
            let corner = |su: f64, sv: f64| add(p.centre, add(scale(u, su * h), scale(v, sv * h)));
            Square {
                corners: [
                    corner(-1.0, -1.0),
                    corner(1.0, -1.0),
                    corner(1.0, 1.0),
                    corner(-1.0, 1.0),
                ],
                direction: p.direction,
            }
        })
        .collect();
    let mut bvh =
        Bvh::build_with_squares(&scene.positions, &scene.triangles, &squares, shift_of(grid));
    let patches_cl = prepare_patches(patches, grid);
    let tol = (PLANE_TOL * grid.size) as f32;
    square_certificates(&mut bvh, &patches_cl, tol as f64);
    if bvh.stats.max_depth as usize + 2 > bvh::STACK {
        return Err(BakeError::TooLarge {
            stage: "form factors",
            detail: format!(
                "BVH depth {} exceeds the traversal stack of {}",
                bvh.stats.max_depth,
                bvh::STACK
            ),
        });
    }
    Ok(Prepared {
        patches: patches_cl,
        bvh,
        tol,
        rules: rule_table(options.quadrature_tol),
        samples: options.samples,
        rays: options.rays,
        certificates: options.certificates,
        gauss: (1..=options.samples).map(gauss_legendre).collect(),
    })
}

/// Gives each patch square's two triangles the certificate of the scene
/// polygon the square lies on, if any: the first scene triangle parallel to
/// the square (normals within 1e-6) crossed by a segment of ±2 `tol`
/// through the square's centre along its normal. A wall's patch squares
/// then prove as much as the wall (a ray crossing a wall may hit either
/// the wall or a coincident square first).
fn square_certificates(bvh: &mut Bvh, patches: &[ClPatch], tol: f64) {
    let mut leaves: Vec<(u32, u32)> = bvh
        .tris
        .iter()
        .enumerate()
        .filter(|(_, t)| t.patch != bvh::SCENE)
        .map(|(k, t)| (t.patch, k as u32))
        .collect();
    leaves.sort_unstable();
    let found: Vec<Option<Cert>> = leaves
        .par_iter()
        .map(|&(patch, _)| {
            let p = P64::from(&patches[patch as usize]);
            let o = sub(p.c, scale(p.n, 2.0 * tol));
            let d = scale(p.n, 4.0 * tol);
            bvh.any_hit(o, d, |k, _| {
                let t = &bvh.tris[k as usize];
                if t.patch != bvh::SCENE {
                    return true;
                }
                let nt = cross(sub(f64s(t.v1), f64s(t.v0)), sub(f64s(t.v2), f64s(t.v0)));
                let len = dot(nt, nt).sqrt();
                !(len > 0.0 && (dot(nt, p.n) / len).abs() > 1.0 - 1e-6)
            })
            .map(|k| bvh.certs[k as usize])
        })
        .collect();
    for (&(_, leaf), cert) in leaves.iter().zip(found) {
        if let Some(c) = cert {
            bvh.certs[leaf as usize] = c;
            bvh.stats.squares_on_scene_polygons += 1;
        }
    }
    // Both halves of a square were counted.
    bvh.stats.squares_on_scene_polygons /= 2;
}

/// `lowbias32` (Chris Wellons' integer hash), as `hash32` in the kernel.
pub fn hash32(mut x: u32) -> u32 {
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846ca68b);
    x ^= x >> 16;
    x
}

/// Gauss–Legendre nodes on [−1, 1] and weights normalised to sum 1, for
/// `m` points (Newton's iteration on the Legendre polynomial `P_m` from
/// the Chebyshev guesses, to f64 precision; Golub and Welsch's classic
/// tabulated values agree). Ascending nodes.
pub fn gauss_legendre(m: u32) -> Vec<(f64, f64)> {
    let m = m as usize;
    let mut out = Vec::with_capacity(m);
    for k in 0..m {
        let mut x = -(std::f64::consts::PI * (k as f64 + 0.75) / (m as f64 + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            // P_m(x) and P_m'(x) by the three-term recurrence.
            let (mut p0, mut p1) = (1.0f64, x);
            for j in 2..=m {
                let p2 = ((2 * j - 1) as f64 * x * p1 - (j - 1) as f64 * p0) / j as f64;
                p0 = p1;
                p1 = p2;
            }
            dp = m as f64 * (x * p1 - p0) / (x * x - 1.0);
            let step = p1 / dp;
            x -= step;
            if step.abs() < 1e-16 {
                break;
            }
        }
        let w = 2.0 / ((1.0 - x * x) * dp * dp);
        out.push((x, 0.5 * w));
    }
    out
}

/// Error model of the `m`-point Gauss–Legendre product rule over the
/// emitter: relative error `≤ C_m ρ^(2m)`, `ρ = emitter side / centre
/// distance`, with `C_m` the worst of measured errors against a 16 × 16
/// rule for unit squares in nine configurations (parallel at distances 1,
/// 2, 4 and offset by 2, perpendicular adjacent, with gaps of 1 and 3,
/// diagonal, far): e.g. adjacent perpendicular squares are within 2e-5 at
/// `m = 3` and 2e-6 at `m = 4`, where the midpoint rule was 4e-3 and 2e-3.
/// Beyond `m = 4` the model extrapolates with `C_m = 5e-4`.
pub const QUADRATURE_ERROR: [f64; 4] = [0.45, 0.09, 1.5e-3, 5e-4];

/// Float offset of the thresholds in the rule table.
pub const RULE_THRESHOLDS: usize = (MAX_SAMPLES * (MAX_SAMPLES + 1)) as usize;

/// The table the kernel reads: for `m = 1..=MAX_SAMPLES`, at float offset
/// `m (m − 1)`, `m` pairs (node, weight) of [`gauss_legendre`] in f32; then
/// at [`RULE_THRESHOLDS`]` + m` the largest `ρ²` for which the `m`-point
/// rule meets `tol` by [`QUADRATURE_ERROR`] (index 0 unused).
pub fn rule_table(tol: f64) -> Vec<f32> {
    let mut t: Vec<f32> = (1..=MAX_SAMPLES)
        .flat_map(gauss_legendre)
        .flat_map(|(x, w)| [x as f32, w as f32])
        .collect();
    debug_assert_eq!(t.len(), RULE_THRESHOLDS);
    t.push(0.0);
    for m in 1..=MAX_SAMPLES {
        let c = QUADRATURE_ERROR[(m as usize - 1).min(QUADRATURE_ERROR.len() - 1)];
        // C ρ^(2m) ≤ tol  ⇔  ρ² ≤ (tol / C)^(1/m).
        t.push((tol / c).powf(1.0 / m as f64) as f32);
    }
    t
}

/// Whether `b`'s centre lies above `a`'s plane by more than `tol`, in f32
/// with the kernel's exact operations (`front` there).
pub fn front_f32(a: &ClPatch, b: &ClPatch, tol: f32) -> bool {
    let dx = b.c[0] - a.c[0];
    let dy = b.c[1] - a.c[1];
    let dz = b.c[2] - a.c[2];
    let base = dx * a.n[0] + dy * a.n[1] + dz * a.n[2];
    base > tol
}

/// Emitter samples per side for a pair, in f32 with the kernel's exact
/// operations (`samples_for` there).
pub fn samples_for(e: &ClPatch, r: &ClPatch, rules: &[f32], samples: u32) -> u32 {
    let dx = r.c[0] - e.c[0];
    let dy = r.c[1] - e.c[1];
    let dz = r.c[2] - e.c[2];
    let d2 = dx * dx + dy * dy + dz * dz;
    let side = 2.0f32 * e.h;
    let side2 = side * side;
    for k in 1..samples {
        if side2 <= rules[RULE_THRESHOLDS + k as usize] * d2 {
            return k;
        }
    }
    samples
}

/// Per-rule counts of a set of pairs (integers: order-independent sums).
#[derive(Clone, Copy, Debug, Default)]
struct Counts {
    by_rule: [u64; 4],
    evaluated_zero: u64,
    rays: u64,
}

impl Counts {
    fn add_info(&mut self, info: u32, g: f32) {
        let rl = (info >> 24).min(3) as usize;
        self.by_rule[rl] += 1;
        if rl == rule::EVALUATED as usize && g == 0.0 {
            self.evaluated_zero += 1;
        }
        self.rays += (info & 0xff_ffff) as u64;
    }
    fn merge(mut self, o: Counts) -> Counts {
        for k in 0..4 {
            self.by_rule[k] += o.by_rule[k];
        }
        self.evaluated_zero += o.evaluated_zero;
        self.rays += o.rays;
        self
    }
}

/// Unordered pairs in rows `first..end` of an `n × n` upper triangle.
fn pairs_in_rows(n: usize, first: usize, end: usize) -> u64 {
    (first..end).map(|i| (n - 1 - i) as u64).sum()
}

/// Rows from `first` holding about `budget` pairs (at least one row), and at
/// most `max_entries / n` rows.
fn rows_for_budget(n: usize, first: usize, budget: u64, max_entries: usize) -> usize {
    let max_rows = (max_entries / n.max(1)).max(1);
    let mut end = first;
    let mut pairs = 0u64;
    while end < n && (end == first || (pairs < budget && end - first < max_rows)) {
        pairs += (n - 1 - end) as u64;
        end += 1;
    }
    end
}

/// The CPU reference over all pairs: `G` in the upper triangle of `g`.
fn cpu_pairs(prep: &Prepared, g: &mut [f32], progress: &mut dyn FnMut(u64, u64)) -> (Counts, u64) {
    let n = prep.patches.len();
    let total = pairs_in_rows(n, 0, n);
    let mut counts = Counts::default();
    let mut done = 0u64;
    let mut first = 0usize;
    let mut batches = 0u64;
    // Blocks of about 1/64 of the pairs, so progress moves smoothly.
    let budget = (total / 64).max(4096);
    while first < n {
        let end = rows_for_budget(n, first, budget, usize::MAX);
        let c = g[first * n..end * n]
            .par_chunks_mut(n)
            .enumerate()
            .map(|(k, row)| {
                let i = first + k;
                let mut c = Counts::default();
                for (j, out) in row.iter_mut().enumerate().skip(i + 1) {
                    let (gij, info) = cpu_pair(prep, i, j);
                    *out = gij as f32;
                    c.add_info(info, *out);
                }
                c
            })
            .reduce(Counts::default, Counts::merge);
        counts = counts.merge(c);
        done += pairs_in_rows(n, first, end);
        batches += 1;
        progress(done, total);
        first = end;
    }
    (counts, batches)
}

/// Most entries (rows × n) of one OpenCL batch: 16 Mi, 64 MiB per output
/// buffer.
const MAX_BATCH_ENTRIES: usize = 16 << 20;

/// The kernel over all pairs, in batches of rows sized to about
/// `batch_seconds` each: `G` in the upper triangle of `g`. Returns the
/// counts, the batch count and the summed device time.
fn cl_pairs(
    gpu: &Gpu,
    prep: &Prepared,
    batch_seconds: f64,
    g: &mut [f32],
    progress: &mut dyn FnMut(u64, u64),
) -> Result<(Counts, u64, f64), BakeError> {
    let n = prep.patches.len();
    let total = pairs_in_rows(n, 0, n);
    if total == 0 {
        progress(0, 0);
        return Ok((Counts::default(), 0, 0.0));
    }
    let program = gpu.build("form_factor.cl", KERNEL_SOURCE, "")?;
    let kernel = gpu.kernel(&program, "form_factors")?;
    let bvh = &prep.bvh;
    // OpenCL forbids empty buffers: an empty scene gets one triangle-less
    // root node (count 0 would mean an inner node), so give it a leaf.
    let nodes: Vec<Node> = if bvh.tris.is_empty() {
        vec![Node {
            min: [1.0; 3],
            left: 0,
            max: [-1.0; 3],
            count: 1,
        }]
    } else {
        bvh.nodes.clone()
    };
    let max_rows = (MAX_BATCH_ENTRIES / n.max(1)).max(1).min(n.max(1));
    let out_len = max_rows * n.max(1);
    let bytes = (prep.patches.len() * PATCH_BYTES
        + nodes.len() * std::mem::size_of::<Node>()
        + bvh.tris.len() * std::mem::size_of::<Tri>()
        + bvh.certs.len() * std::mem::size_of::<Cert>()
        + out_len * 8) as u64;
    gpu.check_total("form factors", bytes)?;
    let patch_buf = gpu.upload("patches", &prep.patches, Access::ReadOnly)?;
    let node_buf = gpu.upload("BVH nodes", &nodes, Access::ReadOnly)?;
    let tri_buf = gpu.upload("BVH triangles", &bvh.tris, Access::ReadOnly)?;
    let cert_buf = gpu.upload("occlusion certificates", &bvh.certs, Access::ReadOnly)?;
    let g_buf = gpu.buffer::<f32>("form-factor batch", out_len, Access::WriteOnly)?;
    let info_buf = gpu.buffer::<u32>("pair info batch", out_len, Access::WriteOnly)?;
    let local = gpu.local_size(&kernel, 64);
    let (n_u32, samples, rays) = (n as u32, prep.samples, prep.rays);
    let (tol, certs) = (prep.tol, u32::from(prep.certificates));
    let rule_buf = gpu.upload("quadrature rules", &prep.rules, Access::ReadOnly)?;

    let mut counts = Counts::default();
    let mut device = 0.0;
    let mut batches = 0u64;
    let mut done = 0u64;
    let mut budget = 16384u64;
    let mut first = 0usize;
    while first < n {
        let end = rows_for_budget(n, first, budget, max_rows * n);
        let rows = end - first;
        let (row0, rows_u32) = (first as u32, rows as u32);
        let wall = Instant::now();
        device += gpu.timed("form_factors", || unsafe {
            opencl3::kernel::ExecuteKernel::new(&kernel)
                .set_arg(&patch_buf)
                .set_arg(&n_u32)
                .set_arg(&row0)
                .set_arg(&rows_u32)
                .set_arg(&node_buf)
                .set_arg(&tri_buf)
                .set_arg(&cert_buf)
                .set_arg(&samples)
                .set_arg(&rays)
                .set_arg(&rule_buf)
                .set_arg(&tol)
                .set_arg(&certs)
                .set_arg(&g_buf)
                .set_arg(&info_buf)
                .set_global_work_size(round_up(rows * n, local))
                .set_local_work_size(local)
                .enqueue_nd_range(gpu.queue())
        })?;
        let gb = gpu.download("form-factor batch", &g_buf, rows * n)?;
        let ib = gpu.download("pair info batch", &info_buf, rows * n)?;
        let seconds = wall.elapsed().as_secs_f64();
        for k in 0..rows {
            let i = first + k;
            for j in i + 1..n {
                let v = gb[k * n + j];
                g[i * n + j] = v;
                counts.add_info(ib[k * n + j], v);
            }
        }
        let pairs = pairs_in_rows(n, first, end);
        done += pairs;
        batches += 1;
        progress(done, total);
        // Next batch: the measured rate times the target time, growing at
        // most 4x per batch (the first includes PoCL's kernel compilation).
        let rate = pairs as f64 / seconds.max(1e-6);
        budget = ((rate * batch_seconds) as u64).clamp(1024, budget.saturating_mul(4));
        first = end;
    }
    Ok((counts, batches, device))
}

/// Computes the form factors of `patches` (from voxelizing `scene` on
/// `grid`) with visibility against `scene`'s triangles. `progress(done,
/// total)` is called with pair counts between batches.
pub fn form_factors(
    scene: &Scene,
    patches: &[Patch],
    grid: &Grid,
    options: &FormFactorOptions,
    backend: &Backend,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<FormFactors, BakeError> {
    let start = Instant::now();
    let prep = prepare(scene, patches, grid, options)?;
    let n = patches.len();
    let mut g = vec![0.0f32; n * n];
    let pairs_start = Instant::now();
    let (counts, batches, device, backend_name) = match backend {
        Backend::Cpu => {
            let (c, b) = cpu_pairs(&prep, &mut g, progress);
            (c, b, 0.0, "CPU reference (f64)".to_string())
        }
        Backend::OpenCl(gpu) => {
            let (c, b, d) = cl_pairs(gpu, &prep, options.batch_seconds, &mut g, progress)?;
            (
                c,
                b,
                d,
                format!("OpenCL: {} ({})", gpu.info().name, gpu.info().platform),
            )
        }
    };
    let seconds_pairs = pairs_start.elapsed().as_secs_f64();
    let post = Instant::now();
    let areas: Vec<f64> = patches.iter().map(|p| p.area).collect();
    let mut stats = FormFactorStats {
        backend: backend_name,
        options: Some(options.clone()),
        patches: n as u64,
        pairs_total: pairs_in_rows(n, 0, n),
        pairs_evaluated: counts.by_rule[rule::EVALUATED as usize],
        skipped_backfacing: counts.by_rule[rule::BACKFACING as usize],
        skipped_blocked: counts.by_rule[rule::BLOCKED as usize],
        evaluated_zero: counts.evaluated_zero,
        rays_cast: counts.rays,
        bvh: prep.bvh.stats.clone(),
        batches,
        seconds_pairs,
        seconds_kernels: device,
        ..Default::default()
    };
    let mut out = finish(n, g, &areas, &mut stats)?;
    stats.seconds_post = post.elapsed().as_secs_f64();
    stats.seconds_total = start.elapsed().as_secs_f64();
    stats.pairs_per_second = stats.pairs_total as f64 / seconds_pairs.max(1e-9);
    stats.rays_per_second = stats.rays_cast as f64 / seconds_pairs.max(1e-9);
    out.stats = stats;
    Ok(out)
}

/// Tile edge of the blocked transposing passes.
const TILE: usize = 64;

/// From `G` in the upper triangle of `g` (n × n) to the final matrix:
/// checks, negative clamps, row corrections, removal of patches that see
/// nothing, `F_ij = G_ij / A_i`, `F_ji = G_ij / A_j`, compaction, and the
/// invariant measures. Deterministic (fixed orders, f64 sums).
#[allow(clippy::needless_range_loop)]
fn finish(
    n: usize,
    mut g: Vec<f32>,
    areas: &[f64],
    stats: &mut FormFactorStats,
) -> Result<FormFactors, BakeError> {
    // Row sums of G (both halves), negatives, non-finite values.
    let mut s = vec![0.0f64; n];
    for i in 0..n {
        for j in i + 1..n {
            let v = &mut g[i * n + j];
            if !v.is_finite() {
                return Err(BakeError::Numeric {
                    stage: "form factors",
                    detail: format!("pair ({i}, {j}) gave a non-finite value {v}"),
                });
            }
            if *v < 0.0 {
                stats.negative_clamped += 1;
                stats.most_negative = stats.most_negative.min(*v as f64 / areas[i].max(areas[j]));
                *v = 0.0;
            }
            s[i] += *v as f64;
            s[j] += *v as f64;
        }
    }
    stats.max_row_sum_before = (0..n).map(|i| s[i] / areas[i]).fold(0.0, f64::max);
    // Corrections, in patch order: row i and column i scaled by A_i / S_i.
    for i in 0..n {
        if s[i] / areas[i] > 1.0 + ROW_SUM_TOL {
            stats.row_corrections += 1;
            let factor = areas[i] / s[i];
            for j in 0..n {
                if j == i {
                    continue;
                }
                let idx = if i < j { i * n + j } else { j * n + i };
                let old = g[idx];
                let new = (old as f64 * factor) as f32;
                g[idx] = new;
                s[j] -= old as f64 - new as f64;
            }
            s[i] = areas[i];
        }
    }
    let kept: Vec<usize> = (0..n).filter(|&i| s[i] > 0.0).collect();
    stats.kept = kept.len() as u64;
    stats.removed_patches = (n - kept.len()) as u64;
    // Fill both triangles from G, tile by tile for locality.
    let mut max_recip = 0.0f64;
    for ib in (0..n).step_by(TILE) {
        for jb in (ib..n).step_by(TILE) {
            for i in ib..(ib + TILE).min(n) {
                g[i * n + i] = 0.0;
                for j in jb.max(i + 1)..(jb + TILE).min(n) {
                    let v = g[i * n + j] as f64;
                    let fij = (v / areas[i]) as f32;
                    let fji = (v / areas[j]) as f32;
                    g[i * n + j] = fij;
                    g[j * n + i] = fji;
                    let (a, b) = (areas[i] * fij as f64, areas[j] * fji as f64);
                    let big = a.max(b);
                    if big > 0.0 {
                        max_recip = max_recip.max((a - b).abs() / big);
                    }
                }
            }
        }
    }
    stats.max_reciprocity_error = max_recip;
    // Compact to the kept patches (destination indices never pass sources).
    let k = kept.len();
    if k < n {
        for (a, &i) in kept.iter().enumerate() {
            for (b, &j) in kept.iter().enumerate() {
                g[a * k + b] = g[i * n + j];
            }
        }
        g.truncate(k * k);
        g.shrink_to_fit();
    }
    let out = FormFactors {
        n: k,
        f: g,
        kept,
        // The contour integrals see no sky: a bake by them has none.
        sky: Vec::new(),
        stats: FormFactorStats::default(),
    };
    stats.max_row_sum = out.row_sums().into_iter().fold(0.0, f64::max);
    Ok(out)
}
