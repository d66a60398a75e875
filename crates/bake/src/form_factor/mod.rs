//! Form factors `F_ij` between patches, with visibility (docs/design.md section
//! 1, bake step 3; section 2 for the definition and the invariants).
//!
//! ## Two methods
//! - **Rays** (the default, [`rays`]): cosine-distributed rays from each
//!   patch's real triangle pieces, credited to the patch owning the piece
//!   they hit; symmetrised and scaled to the measured row sums. Right on
//!   real scenes (relief, slivers, pieces a square does not describe), with
//!   Monte Carlo noise of `1/√(N F_ij)` per entry.
//! - **Contour** (`contour.rs`, `cpu.rs` and `crates/bake/kernels/form_factor.cl`): each
//!   patch a square in its mean plane, Lambert's exact point-to-polygon
//!   factor with visibility rays. Exact on planar plates (the analytic view
//!   factor tests), wrong where the square does not describe the geometry:
//!   on Sponza the light after the first bounce came out 58 % too dark.
//!   `contour.rs` describes it.

use crate::compute::Backend;
use crate::error::BakeError;
use radiosity_core::bvh::BvhStats;
use radiosity_core::npy;
use radiosity_core::scene::Scene;
use rayon::prelude::*;
use serde::Serialize;
use std::fmt;
use std::path::Path;

pub(crate) mod batches;
mod contour;
mod cpu;
pub mod rays;
pub mod tracer;
pub use contour::*;
pub use cpu::{cpu_pair, lattice, lattice_offsets};

/// A row sum above `1 + ROW_SUM_TOL` is corrected (and counted). The
/// tolerance is ~8 f32 ulps of 1: the summed f32 entries alone cannot
/// exceed 1 by more.
pub const ROW_SUM_TOL: f64 = 1e-6;

/// Largest matrix [`write_f_npy`] writes: 2 GiB of f32 (n ≤ 23170), beyond
/// which the file is too large to load casually, and the bake should use
/// fewer patches.
pub const NPY_MAX_BYTES: u64 = 2 << 30;

/// How form factors are computed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum FormFactorMethod {
    /// Rays from the patches' real triangle pieces ([`rays`]): the default.
    Rays,
    /// Contour integrals between patch squares with ray visibility (this
    /// module's doc): exact for planar squares, the analytic view factors'
    /// method.
    Contour,
}

impl FormFactorMethod {
    pub fn name(self) -> &'static str {
        match self {
            FormFactorMethod::Rays => "rays",
            FormFactorMethod::Contour => "contour",
        }
    }

    pub fn parse(s: &str) -> Option<FormFactorMethod> {
        match s {
            "rays" => Some(FormFactorMethod::Rays),
            "contour" => Some(FormFactorMethod::Contour),
            _ => None,
        }
    }
}

/// Where the rays method traces its rays (`crate::trace`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub enum RayDevice {
    /// On the OpenCL device when it is not a CPU (a CPU device is the
    /// cores the native traversal runs on faster), else on the CPU.
    #[default]
    Auto,
    /// On the OpenCL device whatever it is (the tests' PoCL).
    Device,
    /// On the CPU.
    Cpu,
}

impl RayDevice {
    pub fn name(self) -> &'static str {
        match self {
            RayDevice::Auto => "auto",
            RayDevice::Device => "device",
            RayDevice::Cpu => "cpu",
        }
    }

    pub fn parse(s: &str) -> Option<RayDevice> {
        match s {
            "auto" => Some(RayDevice::Auto),
            "device" => Some(RayDevice::Device),
            "cpu" => Some(RayDevice::Cpu),
            _ => None,
        }
    }
}

/// Most rays per patch of the rays method.
pub const MAX_RAYS_PER_PATCH: u32 = 1 << 20;

/// Options of the stage.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FormFactorOptions {
    /// The method (default: rays from the real surfaces).
    pub method: FormFactorMethod,
    /// Rays per patch of the rays method, 16..=2^20. Default 16384
    /// ([`rays`] module doc: the noise a smooth wall shows).
    pub rays_per_patch: u32,
    /// Emitter samples per side for near pairs (an `m × m` midpoint grid,
    /// `m ≤ samples`), 1..=16. Default 4.
    pub samples: u32,
    /// Visibility rays per pair, spread over the emitter samples with at
    /// least one per sample (`⌈rays / m²⌉` each), 1..=64. Default 4.
    pub rays: u32,
    /// Target relative error of the quadrature over the emitter, per pair:
    /// `m` is the smallest rule whose error model (see [`QUADRATURE_ERROR`])
    /// meets it, capped at `samples`. Default 1e-3.
    pub quadrature_tol: f64,
    /// Target wall time of one OpenCL batch (rows launched together), in
    /// seconds; kept well below the watchdogs of display GPUs. Default 0.5.
    pub batch_seconds: f64,
    /// Use occlusion certificates to skip blocked pairs (default true; off
    /// only to measure what they save: results are the same).
    pub certificates: bool,
    /// Where the rays method (and the near field) trace their rays.
    pub ray_device: RayDevice,
}

impl Default for FormFactorOptions {
    fn default() -> Self {
        Self {
            method: FormFactorMethod::Rays,
            rays_per_patch: 16384,
            samples: 4,
            rays: 4,
            quadrature_tol: 1e-3,
            batch_seconds: 0.5,
            certificates: true,
            ray_device: RayDevice::Auto,
        }
    }
}

impl FormFactorOptions {
    /// Checks the ranges above.
    pub fn validate(&self) -> Result<(), BakeError> {
        if !(16..=MAX_RAYS_PER_PATCH).contains(&self.rays_per_patch) {
            return Err(BakeError::InvalidOption {
                option: "form-factor rays per patch",
                value: self.rays_per_patch.to_string(),
                expected: format!("16..={MAX_RAYS_PER_PATCH}"),
            });
        }
        if !(1..=MAX_SAMPLES).contains(&self.samples) {
            return Err(BakeError::InvalidOption {
                option: "form-factor samples per side",
                value: self.samples.to_string(),
                expected: format!("1..={MAX_SAMPLES}"),
            });
        }
        if !(1..=MAX_RAYS).contains(&self.rays) {
            return Err(BakeError::InvalidOption {
                option: "form-factor rays per pair",
                value: self.rays.to_string(),
                expected: format!("1..={MAX_RAYS}"),
            });
        }
        if !(self.quadrature_tol.is_finite()
            && self.quadrature_tol > 0.0
            && self.quadrature_tol < 1.0)
        {
            return Err(BakeError::InvalidOption {
                option: "form-factor quadrature tolerance",
                value: self.quadrature_tol.to_string(),
                expected: "a number in (0, 1)".into(),
            });
        }
        if !(self.batch_seconds.is_finite()
            && self.batch_seconds > 0.0
            && self.batch_seconds <= 10.0)
        {
            return Err(BakeError::InvalidOption {
                option: "form-factor batch seconds",
                value: self.batch_seconds.to_string(),
                expected: "a number in (0, 10]".into(),
            });
        }
        Ok(())
    }
}

/// What the stage did: counts by rule, invariant checks, times.
#[derive(Clone, Debug, Default, Serialize)]
pub struct FormFactorStats {
    /// `"OpenCL: <device>"` or `"CPU reference (f64)"`.
    pub backend: String,
    pub options: Option<FormFactorOptions>,
    /// Input patches, patches kept, and patches removed because they see
    /// nothing (row sum 0).
    pub patches: u64,
    pub kept: u64,
    pub removed_patches: u64,
    /// Unordered pairs `n (n − 1) / 2`, and how each was handled.
    pub pairs_total: u64,
    pub pairs_evaluated: u64,
    pub skipped_backfacing: u64,
    pub skipped_blocked: u64,
    /// Evaluated pairs that came out exactly 0 (every ray blocked without
    /// a certificate, or all samples behind the receiver).
    pub evaluated_zero: u64,
    /// Visibility rays cast in all.
    pub rays_cast: u64,
    /// Pairs with a negative `G` from rounding, set to 0, and the most
    /// negative of them as a form factor (`G / max(A_i, A_j)`, ≤ 0).
    pub negative_clamped: u64,
    pub most_negative: f64,
    /// Rows (with their columns) rescaled because they summed above
    /// `1 + ROW_SUM_TOL`, and the largest row sum before and after.
    pub row_corrections: u64,
    pub max_row_sum_before: f64,
    pub max_row_sum: f64,
    /// Largest `|A_i F_ij − A_j F_ji| / max(A_i F_ij, A_j F_ji)`.
    pub max_reciprocity_error: f64,
    pub bvh: BvhStats,
    pub batches: u64,
    /// Wall seconds: the whole stage, the pairs (kernels or CPU reference
    /// including transfers), device time of the kernels, post-processing.
    pub seconds_total: f64,
    pub seconds_pairs: f64,
    pub seconds_kernels: f64,
    pub seconds_post: f64,
    /// `pairs_total / seconds_pairs` and `rays_cast / seconds_pairs`.
    pub pairs_per_second: f64,
    pub rays_per_second: f64,
    /// Rays method: rays that left the scene, met a back face, or met a
    /// piece with no patch.
    pub rays_escaped: u64,
    pub rays_back_face: u64,
    pub rays_unowned: u64,
    /// Rays method: origins drawn on the covered part of a partly covered
    /// piece, not cast (not in `rays_cast`).
    pub rays_covered: u64,
    /// Rays method: the area-weighted fraction of the real hemisphere that
    /// meets front faces, and the area-weighted mean row sum of `F`.
    pub front_fraction: f64,
    pub row_sum_mean: f64,
    /// Rays method: symmetric Sinkhorn iterations and the largest relative
    /// row-sum error they left.
    pub sinkhorn_iterations: u64,
    pub sinkhorn_residual: f64,
}

impl fmt::Display for FormFactorStats {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "form factors on {}", self.backend)?;
        if self
            .options
            .as_ref()
            .is_some_and(|o| o.method == FormFactorMethod::Rays)
        {
            writeln!(
                f,
                "  patches: {} in, {} kept, {} removed (see nothing)",
                self.patches, self.kept, self.removed_patches
            )?;
            writeln!(
                f,
                "  rays: {} cast ({:.3e} rays/s): {} left the scene, {} met a back face, {} a piece with no patch; {} origins on covered parts of pieces not cast",
                self.rays_cast,
                self.rays_per_second,
                self.rays_escaped,
                self.rays_back_face,
                self.rays_unowned,
                self.rays_covered
            )?;
            writeln!(
                f,
                "  row sums (area-weighted mean) {:.4}; real hemisphere meeting front faces {:.4}; max row sum {:.7}; symmetric Sinkhorn {} iterations (residual {:.1e}); max reciprocity error {:.2e}",
                self.row_sum_mean,
                self.front_fraction,
                self.max_row_sum,
                self.sinkhorn_iterations,
                self.sinkhorn_residual,
                self.max_reciprocity_error
            )?;
            return writeln!(
                f,
                "  time: {:.3} s total, {:.3} s rays, {:.3} s post",
                self.seconds_total, self.seconds_pairs, self.seconds_post
            );
        }
        writeln!(
            f,
            "  patches: {} in, {} kept, {} removed (see nothing)",
            self.patches, self.kept, self.removed_patches
        )?;
        writeln!(
            f,
            "  pairs: {} total, {} evaluated ({} came out 0), {} back-facing, {} certified blocked",
            self.pairs_total,
            self.pairs_evaluated,
            self.evaluated_zero,
            self.skipped_backfacing,
            self.skipped_blocked
        )?;
        writeln!(
            f,
            "  rays: {} cast; BVH {} triangles, {} nodes, depth {}, {} quad certificates",
            self.rays_cast,
            self.bvh.triangles,
            self.bvh.nodes,
            self.bvh.max_depth,
            self.bvh.quad_certificates
        )?;
        writeln!(
            f,
            "  invariants: max row sum {:.7} (before corrections {:.7}), {} rows corrected, {} negative entries zeroed (most negative {:.1e}), max reciprocity error {:.2e}",
            self.max_row_sum,
            self.max_row_sum_before,
            self.row_corrections,
            self.negative_clamped,
            self.most_negative,
            self.max_reciprocity_error
        )?;
        writeln!(
            f,
            "  time: {:.3} s total, {:.3} s pairs ({} batches, {:.3} s device), {:.3} s post; {:.3e} pairs/s, {:.3e} rays/s",
            self.seconds_total,
            self.seconds_pairs,
            self.batches,
            self.seconds_kernels,
            self.seconds_post,
            self.pairs_per_second,
            self.rays_per_second
        )
    }
}

/// The result: the `n × n` matrix over the kept patches (row-major f32) and
/// which input patches those are.
#[derive(Clone, Debug)]
pub struct FormFactors {
    pub n: usize,
    /// `F[i * n + j] = F_ij` for kept patches `i`, `j` (indices into `kept`).
    pub f: Vec<f32>,
    /// Indices of the input patches kept, increasing.
    pub kept: Vec<usize>,
    /// Per kept patch, its `(sky cell, T_c)` (`radiosity_bakefile::sky`),
    /// from the rays that left the scene; empty where the method casts
    /// none.
    pub sky: Vec<Vec<(u8, f32)>>,
    pub stats: FormFactorStats,
}

impl FormFactors {
    /// `F_ij` (kept-patch indices).
    pub fn get(&self, i: usize, j: usize) -> f32 {
        self.f[i * self.n + j]
    }

    /// Row sums in f64.
    pub fn row_sums(&self) -> Vec<f64> {
        if self.n == 0 {
            return Vec::new();
        }
        self.f
            .par_chunks(self.n)
            .map(|r| r.iter().map(|&x| x as f64).sum())
            .collect()
    }
}

/// The form factors of a voxelization's patches by `options.method`: rays
/// from the real surfaces (CPU), or contour integrals between the patch
/// squares on `backend` ([`form_factors`]).
pub fn of_voxelization(
    scene: &Scene,
    vox: &crate::voxelize::Voxelization,
    options: &FormFactorOptions,
    backend: &Backend,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<FormFactors, BakeError> {
    options.validate()?;
    match options.method {
        FormFactorMethod::Rays => rays::form_factors(scene, vox, options, backend, progress),
        FormFactorMethod::Contour => {
            form_factors(scene, &vox.patches, &vox.grid, options, backend, progress)
        }
    }
}

/// Writes `F` as an `n × n` float32 `.npy` file (load with `numpy.load`).
/// Refuses matrices above [`NPY_MAX_BYTES`].
pub fn write_f_npy(path: &Path, ff: &FormFactors) -> Result<(), BakeError> {
    let bytes = (ff.n as u64) * (ff.n as u64) * 4;
    if bytes > NPY_MAX_BYTES {
        return Err(BakeError::TooLarge {
            stage: "form factors",
            detail: format!(
                "refusing to write {}: the {}×{} matrix takes {} bytes, above the {} byte limit of .npy exports; use fewer patches",
                path.display(),
                ff.n,
                ff.n,
                bytes,
                NPY_MAX_BYTES
            ),
        });
    }
    npy::write_f32(path, &[ff.n, ff.n], &ff.f).map_err(|e| BakeError::Mismatch {
        stage: "form factors",
        detail: e.to_string(),
    })
}

/// How two results for the same patches differ (OpenCL against the CPU
/// reference).
#[derive(Clone, Debug, Default, Serialize)]
pub struct Comparison {
    pub n: usize,
    /// Largest `|a − b|` over entries.
    pub max_abs_diff: f64,
    /// `‖a − b‖_F / ‖b‖_F`.
    pub rel_frobenius: f64,
    /// Largest row-sum difference.
    pub max_row_sum_diff: f64,
    /// Entries differing by more than `1e-4 · max(|a|, |b|) + 1e-7`.
    pub entries_beyond_1e4: u64,
}

/// Compares two results entry by entry (both must keep the same patches).
pub fn compare(a: &FormFactors, b: &FormFactors) -> Result<Comparison, BakeError> {
    if a.kept != b.kept {
        return Err(BakeError::Mismatch {
            stage: "form factors",
            detail: format!("the results keep different patches ({} vs {})", a.n, b.n),
        });
    }
    let mut c = Comparison {
        n: a.n,
        ..Default::default()
    };
    let (mut num, mut den) = (0.0f64, 0.0f64);
    for (x, y) in a.f.iter().zip(&b.f) {
        let (x, y) = (*x as f64, *y as f64);
        let d = (x - y).abs();
        c.max_abs_diff = c.max_abs_diff.max(d);
        num += d * d;
        den += y * y;
        if d > 1e-4 * x.abs().max(y.abs()) + 1e-7 {
            c.entries_beyond_1e4 += 1;
        }
    }
    c.rel_frobenius = if den > 0.0 {
        (num / den).sqrt()
    } else {
        num.sqrt()
    };
    c.max_row_sum_diff = a
        .row_sums()
        .iter()
        .zip(b.row_sums())
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max);
    Ok(c)
}
