//! The multi-bounce transfer matrix (docs/design.md section 2, bake step 4):
//! from the form factors `F` and the patch albedos `ρ`, per colour channel,
//!
//! - `T_k = Σ_{h=1..k} F (diag(ρ) F)^{h−1}` for `k` bounces, and
//! - `T_∞ = F (I − diag(ρ) F)^{−1}`, the limit,
//!
//! so that at run time one product `H = T · B0` gives the indirect
//! irradiance.
//!
//! **The form computed.** With `Q = F diag(ρ)` (F's columns scaled by the
//! albedo, formed once on the host in O(n²)), `F (diag(ρ) F)^h = Q^h F`, so
//! `T_k = Σ_{h<k} Q^h F`, and two recurrences follow:
//! - Horner: `T_{h+1} = F + Q T_h`: one matrix product per bounce, with the
//!   `F +` fused into the product's epilogue. Scaling `T`'s rows by `ρ` at
//!   every step (`T_{h+1} = F + F (ρ ∘ T_h)`) costs the same product plus an
//!   extra pass; folding `ρ` into `Q` once is cheaper.
//! - Doubling: `T_{2m} = T_m + Q^m T_m` and `Q^{2m} = Q^m Q^m`: two products
//!   double the number of bounces.
//!
//! `T_k` takes `d` doublings (`2d − 1` products, the last square is not
//! needed) and then `k − 2^d` Horner steps, with `d` chosen to minimise the
//! count ([`plan_bounces`]): Horner for `k ≤ 4` (k = 3: two products),
//! doubling beyond (k = 8: 5 products instead of 7). `T_∞` doubles until
//! the term just added is below the f32 resolution of the sum *in every
//! entry*: `(Q^m T_m)_ij ≤ 2^−24 · (T_2m)_ij` (the unit roundoff), measured
//! by the product's epilogue at no extra pass. All matrices are non-negative,
//! so the test cannot be fooled by cancellation, and the terms shrink like
//! `r^m` with `r` the spectral radius of `diag(ρ) F`, so the doublings
//! needed are about `log2(24 ln 2 / −ln r)`, plus one for the entrywise
//! test: measured 9 for r = 0.9, 12 for r = 0.99, 16 for r = 0.999 (the
//! bound `max_i ρ_i Σ_j F_ij` is reported). That is about `2 log2` of the
//! bounces' count where Horner needs the count itself, which makes `T_∞`
//! the default (section "Default" below).
//!
//! **Accuracy.** Storage is f32. Every product accumulates in blocks
//! (`crates/bake/kernels/gemm.cl`): the relative error of each entry of one product of
//! non-negative matrices is at most about `(tile + N / tile) · 2^−24`. The
//! doubling's error grows with the number of products a term went through
//! (a term of order `m` carries about `log2 m` products' errors, weighted by
//! its size `r^m`), so the total stays within a small multiple of one
//! product's bound; the tests check 1e-5 relative Frobenius error for albedo
//! ≤ 0.8 and 1e-3 for 0.99 against the f64 reference, and docs/transfer.md
//! reports the measured errors up to albedo 0.999.
//!
//! **Skipping what the scene does not need.**
//! - Channels with identical albedos everywhere are computed once (grey
//!   scenes: one matrix instead of three; [`Transfer::channel`] returns the
//!   shared one).
//! - Zero-albedo patches end every chain: `Q`'s column j is zero when
//!   `ρ_j = 0`. Patches are reordered (stably) so that those come last;
//!   their columns then form whole zero tiles of every power of `Q`, which
//!   the product skips. The order is restored on download.
//! - All-zero tiles of either operand are skipped in every product (tile
//!   flags, [`crate::gemm`]); closed rooms make `F`, `Q^m` and `T`
//!   block-sparse. The skipped fraction is reported.
//!
//! **Safety.** Albedos outside `[0, 1)` and non-finite or negative form
//! factors are rejected, naming the patch or entry. A non-finite value in
//! any product is an error naming the step ([`BakeError::Numeric`]). A series
//! that has not converged after [`MAX_DOUBLINGS`] doublings (2^40 bounces)
//! is an error.
//!
//! **Default.** [`Bounces::Infinite`]: it is the physically complete answer
//! (in a closed room of uniform albedo ρ, `T_3` misses a fraction ρ³ of the
//! converged light: 51 % at ρ = 0.8, 73 % at ρ = 0.9) and with doubling it
//! costs `2d − 1` products for `d` doublings: 17 at r = 0.9 against 2 for
//! `T_3` and 5 for `T_8` (docs/transfer.md measures the times). The bake
//! runs once per scene; the run-time cost of `T` does not depend on `k`.
//!
//! The CPU backend is the f64 reference ([`reference()`]): Horner with dense
//! products for `T_k`, an LU solve of `X (I − diag(ρ) F) = F` for `T_∞`
//! (faer).

use crate::compute::Backend;
use crate::error::BakeError;
use crate::gemm::{DeviceMatrix, Gemm, GemmConfig, GemmRun};
use faer::linalg::solvers::Solve as _;
use serde::Serialize;
use std::time::Instant;

/// The stage name in errors.
pub const STAGE: &str = "transfer";

/// Unit roundoff of f32: the infinite series stops when every entry of the
/// term just added is at most this fraction of the sum.
pub const CONVERGED_RATIO: f64 = 1.0 / (1u64 << 24) as f64;

/// Doublings after which an infinite series that has not converged is an
/// error: 2^40 bounces, beyond the 2^28 that albedo 1 − 1e-7 needs.
pub const MAX_DOUBLINGS: u32 = 40;

/// The most bounces a finite `T_k` may fold in: beyond it the series'
/// tail `Σ_{h>k} F (ρF)^{h−1}`, at most `ρ_max^k / (1 − ρ_max)` of `T_∞`
/// with every albedo below [`radiosity_core::scene::ALBEDO_MAX`] (0.99) and
/// row sums ≤ 1, is below f32's unit roundoff: `T_k` is `T_∞` to the last
/// bit a bake stores, and the LU solve of `T_∞` is exact and faster than
/// the k products (time grows linearly in k: a billion bounces never
/// finished). `0.99^2114 / 0.01 < 2^−24 ≤ 0.99^2113 / 0.01`
/// (tests/transfer.rs).
pub const MAX_USEFUL_BOUNCES: u32 = 2114;

/// How many bounces of light `T` holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum Bounces {
    /// `k ≥ 1` bounces: `T_k`.
    K(u32),
    /// The converged limit `T_∞`.
    Infinite,
}

impl Default for Bounces {
    /// Infinite: see the module's "Default" section.
    fn default() -> Self {
        Bounces::Infinite
    }
}

impl std::fmt::Display for Bounces {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Bounces::K(k) => write!(f, "{k}"),
            Bounces::Infinite => write!(f, "infinite"),
        }
    }
}

/// How `T_∞` is computed on OpenCL.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub enum InfiniteMethod {
    /// A blocked LU solve of `X (I − diag(ρ) F) = F` ([`crate::solve`]):
    /// `8/3 N³` flops per channel, whatever the albedo.
    #[default]
    Solve,
    /// Doubling the series until it converges: `2 N³` per product, `2d − 1`
    /// products for `d` doublings (9 at spectral radius 0.9, 16 at 0.999).
    Doubling,
}

impl InfiniteMethod {
    /// `solve` or `doubling`.
    pub fn parse(s: &str) -> Option<InfiniteMethod> {
        match s {
            "solve" | "lu" => Some(InfiniteMethod::Solve),
            "doubling" => Some(InfiniteMethod::Doubling),
            _ => None,
        }
    }
}

/// Options of the transfer stage.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TransferOptions {
    pub bounces: Bounces,
    /// How `T_∞` is computed (OpenCL; the CPU reference always solves).
    /// A spectral bound `max_i ρ_i Σ_j F_ij ≥ 1` (form factors whose rows sum
    /// above 1) falls back to doubling, which detects divergence.
    pub infinite: InfiniteMethod,
    /// Skip all-zero tiles in the products (on by default; off only to
    /// measure what skipping saves: the result is the same bit for bit).
    pub skip_zero_tiles: bool,
    /// The OpenCL product's configuration; `None` (the default): the
    /// device's, for this size ([`GemmConfig::for_device`]).
    pub gemm: Option<GemmConfig>,
}

impl Default for TransferOptions {
    fn default() -> Self {
        TransferOptions {
            bounces: Bounces::default(),
            infinite: InfiniteMethod::default(),
            skip_zero_tiles: true,
            gemm: None,
        }
    }
}

/// What happened to one colour channel.
#[derive(Clone, Debug, Default, Serialize)]
pub struct ChannelStats {
    /// 0, 1, 2 = R, G, B.
    pub channel: usize,
    /// "LU solve", "doubling", "Horner" or "f64 reference".
    pub method: String,
    /// The earlier channel with the same albedos whose matrix this one
    /// shares (nothing was computed for it).
    pub shared_with: Option<usize>,
    /// `max_i ρ_i Σ_j F_ij`: the ∞-norm of `diag(ρ) F`, a bound on the
    /// spectral radius that rules the convergence.
    pub spectral_bound: f64,
    /// Patches with zero albedo in this channel.
    pub zero_albedo_patches: u64,
    /// Doublings and Horner steps taken, and the bounces summed (0 for the
    /// CPU reference's exact solve of `T_∞`).
    pub doublings: u32,
    pub horner_steps: u32,
    pub terms: u64,
    /// The last term's largest entry relative to the sum (`T_∞`: at most
    /// [`CONVERGED_RATIO`]).
    pub last_term_ratio: f64,
    pub gemms: u32,
    pub tile_products: u64,
    pub skipped_tiles: u64,
    /// Device seconds of the products, and GFLOP executed.
    pub seconds_gemm: f64,
    pub gflop: f64,
}

/// Statistics of one transfer computation.
#[derive(Clone, Debug, Default, Serialize)]
pub struct TransferStats {
    /// "OpenCL: device" or "CPU f64 reference".
    pub backend: String,
    /// The product's configuration (OpenCL).
    pub gemm_config: String,
    pub n: usize,
    /// `n` padded to the product's tile.
    pub padded: usize,
    pub bounces: Bounces,
    pub grey: bool,
    /// Channels computed (1 for grey scenes, up to 3).
    pub channels_computed: usize,
    pub per_channel: Vec<ChannelStats>,
    /// Over all channels: the largest spectral bound, the most doublings,
    /// bounces summed, products, tile products and skipped tiles.
    pub spectral_bound: f64,
    pub doublings: u32,
    pub terms: u64,
    pub gemms: u32,
    pub tile_products: u64,
    pub skipped_tiles: u64,
    pub skipped_fraction: f64,
    /// GFLOP executed, device seconds of the products and their rate.
    pub gflop: f64,
    pub seconds_gemm: f64,
    pub gflops: f64,
    /// Wall-clock seconds of the whole stage (validation, uploads,
    /// downloads included).
    pub seconds_total: f64,
}

impl std::fmt::Display for TransferStats {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(
            f,
            "transfer: n = {} (padded {}), bounces {}, {} channel(s) computed{}, {}",
            self.n,
            self.padded,
            self.bounces,
            self.channels_computed,
            if self.grey { " (grey)" } else { "" },
            self.backend
        )?;
        if !self.gemm_config.is_empty() {
            writeln!(f, "  GEMM: {}", self.gemm_config)?;
        }
        for c in &self.per_channel {
            let name = ["R", "G", "B"].get(c.channel).unwrap_or(&"?");
            match c.shared_with {
                Some(s) => writeln!(f, "  {name}: same albedos as {}, shared", ["R", "G", "B"][s])?,
                None if c.method == "LU solve" => writeln!(
                    f,
                    "  {name}: spectral bound {:.6}, {} zero-albedo patches, LU solve: {} GEMM launches",
                    c.spectral_bound, c.zero_albedo_patches, c.gemms
                )?,
                None => writeln!(
                    f,
                    "  {name}: spectral bound {:.6}, {} zero-albedo patches, {} doublings + {} Horner steps = {} bounces, last term / sum {:.2e}, {} GEMMs, {:.1} % tiles skipped",
                    c.spectral_bound,
                    c.zero_albedo_patches,
                    c.doublings,
                    c.horner_steps,
                    c.terms,
                    c.last_term_ratio,
                    c.gemms,
                    100.0 * ratio(c.skipped_tiles, c.tile_products)
                )?,
            }
        }
        write!(
            f,
            "  {} GEMMs, {:.1} GFLOP executed in {:.3} s of device time ({:.1} GFLOP/s), {:.1} % of tile products skipped; {:.3} s in all",
            self.gemms,
            self.gflop,
            self.seconds_gemm,
            self.gflops,
            100.0 * self.skipped_fraction,
            self.seconds_total
        )
    }
}

fn ratio(a: u64, b: u64) -> f64 {
    if b == 0 {
        0.0
    } else {
        a as f64 / b as f64
    }
}

/// The transfer matrices: one per colour channel, or one shared by all
/// three when the scene is grey.
#[derive(Clone, Debug)]
pub struct Transfer {
    pub n: usize,
    /// 1 channel if grey, else 3; each `n × n` row-major, row i = `T_i·`.
    pub channels: Vec<Vec<f32>>,
    pub grey: bool,
    pub stats: TransferStats,
}

impl Transfer {
    /// Channel `c` (0, 1, 2 = R, G, B): the shared matrix when grey.
    pub fn channel(&self, c: usize) -> &[f32] {
        assert!(c < 3, "colour channel {c} does not exist (0, 1, 2)");
        if self.grey {
            &self.channels[0]
        } else {
            &self.channels[c]
        }
    }

    /// `H = T · B0` for one channel in f64 (the run-time gather, for tests
    /// and checks).
    pub fn apply(&self, c: usize, b0: &[f64]) -> Vec<f64> {
        let t = self.channel(c);
        (0..self.n)
            .map(|i| {
                t[i * self.n..(i + 1) * self.n]
                    .iter()
                    .zip(b0)
                    .map(|(&t, &b)| t as f64 * b)
                    .sum()
            })
            .collect()
    }
}

/// Padded `n × n` matrices the OpenCL transfer keeps on the device at once
/// with `options`: 2 for the LU solve, 3 for doubling, 5 when Horner steps
/// keep `F` and `Q` (as `cl_channel` and `solve::lu_channel` check).
pub fn cl_matrices(options: &TransferOptions) -> u64 {
    match options.bounces {
        Bounces::Infinite if options.infinite == InfiniteMethod::Solve => 2,
        Bounces::Infinite => 3,
        Bounces::K(k) if plan_bounces(k).1 > 0 => 5,
        Bounces::K(_) => 3,
    }
}

/// `(doublings, horner_steps)` for `T_k` with the fewest products:
/// `d` doublings cost `2d − 1` products and reach `2^d` bounces, each
/// Horner step one product and one bounce.
pub fn plan_bounces(k: u32) -> (u32, u32) {
    assert!(k >= 1, "at least one bounce");
    let mut best = (0, k - 1);
    let mut d = 1;
    while d < 32 && (1u64 << d) <= k as u64 {
        let plan = (d, k - (1u32 << d));
        if plan_cost(plan) < plan_cost(best) {
            best = plan;
        }
        d += 1;
    }
    best
}

fn plan_cost((d, h): (u32, u32)) -> u32 {
    if d == 0 {
        h
    } else {
        2 * d - 1 + h
    }
}

/// Products `plan_bounces(k)` takes.
pub fn planned_gemms(k: u32) -> u32 {
    plan_cost(plan_bounces(k))
}

/// Doublings `T_∞` is expected to need for a spectral bound `r`: the
/// smallest `d` with `r^(2^d) ≤ 2^−24` (at least 1).
pub fn expected_doublings(r: f64) -> u32 {
    if !(r > 0.0) {
        return 1;
    }
    if r >= 1.0 {
        return MAX_DOUBLINGS;
    }
    let m = (CONVERGED_RATIO.ln() / r.ln()).max(1.0);
    (m.log2().ceil() as u32).clamp(1, MAX_DOUBLINGS)
}

/// Checks the inputs: `f` is `n × n`, finite and non-negative; `albedo`
/// has `n` entries, each component in `[0, 1)`. Returns the spectral bound
/// `max_i ρ_i Σ_j F_ij` per channel.
pub fn validate(f: &[f32], n: usize, albedo: &[[f32; 3]]) -> Result<[f64; 3], BakeError> {
    if f.len() != n * n {
        return Err(BakeError::Mismatch {
            stage: "transfer",
            detail: format!(
                "the form-factor matrix has {} entries, not n × n = {n} × {n}",
                f.len()
            ),
        });
    }
    if albedo.len() != n {
        return Err(BakeError::Mismatch {
            stage: "transfer",
            detail: format!("{} albedos for {n} patches", albedo.len()),
        });
    }
    for (i, a) in albedo.iter().enumerate() {
        for (c, &v) in a.iter().enumerate() {
            if !(0.0..1.0).contains(&v) {
                return Err(BakeError::Numeric {
                    stage: STAGE,
                    detail: format!(
                        "patch {i} has albedo {v} in channel {}: albedos must lie in [0, 1) \
                         for the series of bounces to converge",
                        ["R", "G", "B"][c]
                    ),
                });
            }
        }
    }
    let mut bound = [0.0f64; 3];
    for i in 0..n {
        let row = &f[i * n..(i + 1) * n];
        let mut sum = 0.0f64;
        for (j, &v) in row.iter().enumerate() {
            if !(v >= 0.0) || !v.is_finite() {
                return Err(BakeError::Numeric {
                    stage: STAGE,
                    detail: format!(
                        "input form factor F[{i}][{j}] = {v}: form factors must be finite and \
                         non-negative"
                    ),
                });
            }
            sum += v as f64;
        }
        for c in 0..3 {
            bound[c] = bound[c].max(albedo[i][c] as f64 * sum);
        }
    }
    Ok(bound)
}

/// For each channel, the earlier channel with bitwise identical albedos,
/// if any.
fn shared_channels(albedo: &[[f32; 3]]) -> [Option<usize>; 3] {
    let mut shared = [None; 3];
    for c in 1..3 {
        shared[c] = (0..c).find(|&e| {
            shared[e].is_none() && albedo.iter().all(|a| a[c].to_bits() == a[e].to_bits())
        });
    }
    shared
}

/// Computes the transfer matrices of `f` (row-major `n × n`, row i =
/// `F_i·`) with per-patch albedos, on `backend`. `progress(done, total)`
/// counts products (the total for `T_∞` is an estimate from the spectral
/// bound and grows if more are needed).
pub fn transfer(
    f: &[f32],
    n: usize,
    albedo: &[[f32; 3]],
    options: &TransferOptions,
    backend: &Backend,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<Transfer, BakeError> {
    let start = Instant::now();
    if let Bounces::K(0) = options.bounces {
        return Err(BakeError::InvalidOption {
            option: "bounces",
            value: "0".into(),
            expected: "at least 1, or infinite".into(),
        });
    }
    let bounds = validate(f, n, albedo)?;
    let shared = shared_channels(albedo);
    // With no patch, every channel is trivially the same.
    let grey = n == 0 || (shared[1] == Some(0) && shared[2] == Some(0));
    let unique: Vec<usize> = (0..3).filter(|&c| shared[c].is_none()).collect();
    let mut stats = TransferStats {
        n,
        bounces: options.bounces,
        grey,
        channels_computed: unique.len(),
        spectral_bound: unique.iter().map(|&c| bounds[c]).fold(0.0, f64::max),
        ..TransferStats::default()
    };
    let solves = |c: usize| {
        options.bounces == Bounces::Infinite
            && options.infinite == InfiniteMethod::Solve
            && bounds[c] < 1.0
    };
    let mut tile = 0;
    let per_channel_gemms = |c: usize, tile: usize| -> u64 {
        match options.bounces {
            Bounces::K(k) => planned_gemms(k) as u64,
            Bounces::Infinite if solves(c) && tile > 0 => crate::solve::launches_for(n, tile),
            Bounces::Infinite => 2 * expected_doublings(bounds[c]) as u64 - 1,
        }
    };
    let gemm = match backend {
        Backend::OpenCl(gpu) => {
            let g = match options.gemm {
                Some(config) => Gemm::with_config(gpu, config)?,
                None => Gemm::new(gpu, n)?,
            };
            stats.backend = format!("OpenCL: {} ({})", gpu.info().name, gpu.info().platform);
            stats.gemm_config = g.config().to_string();
            stats.padded = if n == 0 { 0 } else { g.padded(n) };
            tile = g.config().tile;
            Some(g)
        }
        Backend::Cpu => {
            stats.backend = "CPU f64 reference (faer)".into();
            stats.padded = n;
            None
        }
    };

    let mut total: u64 = unique.iter().map(|&c| per_channel_gemms(c, tile)).sum();
    let mut done = 0u64;
    progress(0, total);

    let mut computed: Vec<Option<Vec<f32>>> = vec![None, None, None];
    for &c in &unique {
        let rho: Vec<f32> = albedo.iter().map(|a| a[c]).collect();
        let mut cs = ChannelStats {
            channel: c,
            spectral_bound: bounds[c],
            zero_albedo_patches: rho.iter().filter(|&&r| r == 0.0).count() as u64,
            ..ChannelStats::default()
        };
        let t = if n == 0 {
            Vec::new()
        } else {
            match &gemm {
                Some(g) if solves(c) => {
                    cs.method = "LU solve".into();
                    let mut tick = || {
                        done += 1;
                        progress(done, total.max(done));
                    };
                    let (t, run) =
                        crate::solve::lu_channel(g, f, n, &rho, c, bounds[c], &mut tick)?;
                    cs.gemms = run.launches;
                    cs.tile_products = run.tile_products;
                    cs.seconds_gemm = run.seconds;
                    cs.gflop = run.gflop;
                    cs.terms = 0;
                    t
                }
                Some(g) => {
                    cs.method = match options.bounces {
                        Bounces::Infinite => "doubling".into(),
                        Bounces::K(_) => "doubling and Horner".into(),
                    };
                    let mut tick = |extra: bool| {
                        done += 1;
                        if extra && done > total {
                            total = done;
                        }
                        progress(done, total);
                    };
                    cl_channel(g, f, n, &rho, options, &mut cs, &mut tick)?
                }
                None => {
                    cs.method = "f64 reference".into();
                    let rho64: Vec<f64> = rho.iter().map(|&r| r as f64).collect();
                    let t = reference(f, n, &rho64, options.bounces)?;
                    match options.bounces {
                        Bounces::K(k) => {
                            cs.horner_steps = k - 1;
                            cs.terms = k as u64;
                        }
                        // An exact solve: no series, no terms.
                        Bounces::Infinite => cs.terms = 0,
                    }
                    done += per_channel_gemms(c, tile);
                    progress(done, total);
                    let t32: Vec<f32> = t.iter().map(|&x| x as f32).collect();
                    if let Some(e) = t32.iter().position(|x| !x.is_finite()) {
                        return Err(BakeError::Numeric {
                            stage: STAGE,
                            detail: format!(
                                "the f64 reference produced a non-finite value at T[{}][{}] (channel {})",
                                e / n,
                                e % n,
                                ["R", "G", "B"][c]
                            ),
                        });
                    }
                    t32
                }
            }
        };
        stats.doublings = stats.doublings.max(cs.doublings);
        stats.terms = stats.terms.max(cs.terms);
        stats.gemms += cs.gemms;
        stats.tile_products += cs.tile_products;
        stats.skipped_tiles += cs.skipped_tiles;
        stats.gflop += cs.gflop;
        stats.seconds_gemm += cs.seconds_gemm;
        stats.per_channel.push(cs);
        computed[c] = Some(t);
    }
    for (c, s) in shared.iter().enumerate() {
        if let Some(s) = *s {
            stats.per_channel.push(ChannelStats {
                channel: c,
                shared_with: Some(s),
                ..ChannelStats::default()
            });
        }
    }
    stats.per_channel.sort_by_key(|c| c.channel);
    let channels: Vec<Vec<f32>> = if grey {
        vec![computed[0].take().expect("channel 0 is always computed")]
    } else {
        // Last channel first, so that a shared channel clones its source
        // before the source is moved out.
        let mut v: Vec<Vec<f32>> = (0..3)
            .rev()
            .map(|c| match shared[c] {
                Some(s) => computed[s].clone().expect("an earlier channel is computed"),
                None => computed[c].take().expect("computed"),
            })
            .collect();
        v.reverse();
        v
    };
    stats.skipped_fraction = ratio(stats.skipped_tiles, stats.tile_products);
    stats.gflops = if stats.seconds_gemm > 0.0 {
        stats.gflop / stats.seconds_gemm
    } else {
        0.0
    };
    stats.seconds_total = start.elapsed().as_secs_f64();
    Ok(Transfer {
        n,
        channels,
        grey,
        stats,
    })
}

/// One channel on OpenCL. `tick(extra)` reports one product done (`extra`:
/// beyond the planned count is allowed).
fn cl_channel(
    g: &Gemm,
    f: &[f32],
    n: usize,
    rho: &[f32],
    options: &TransferOptions,
    cs: &mut ChannelStats,
    tick: &mut dyn FnMut(bool),
) -> Result<Vec<f32>, BakeError> {
    let name = ["R", "G", "B"][cs.channel];
    // Zero-albedo patches last (stable), so that their zero columns of Q
    // form whole zero tiles; `order[new] = old`.
    let order: Vec<usize> = (0..n)
        .filter(|&i| rho[i] != 0.0)
        .chain((0..n).filter(|&i| rho[i] == 0.0))
        .collect();
    let permuted = order.iter().enumerate().any(|(a, &b)| a != b);
    let fp: std::borrow::Cow<[f32]> = if permuted {
        let mut p = vec![0.0f32; n * n];
        for (a, &i) in order.iter().enumerate() {
            for (b, &j) in order.iter().enumerate() {
                p[a * n + b] = f[i * n + j];
            }
        }
        p.into()
    } else {
        f.into()
    };
    // Q = F diag(ρ): one rounding per entry.
    let rho_p: Vec<f64> = order.iter().map(|&i| rho[i] as f64).collect();
    let q: Vec<f32> = fp
        .chunks_exact(n)
        .flat_map(|row| row.iter().zip(&rho_p).map(|(&x, &r)| (x as f64 * r) as f32))
        .collect();

    let (doublings_planned, horner_steps) = match options.bounces {
        Bounces::K(k) => plan_bounces(k),
        Bounces::Infinite => (MAX_DOUBLINGS, 0),
    };
    // Horner steps read F and Q themselves; otherwise (pure doubling) their
    // buffers are recycled.
    let keep = horner_steps > 0;
    // Device memory: F, Q and one more buffer suffice for doubling (the
    // outputs of the doubling and the squaring recycle the inputs they
    // replace); at most five when F and Q are kept.
    let buffers: u64 = if keep { 5 } else { 3 };
    g.gpu().check_total(STAGE, buffers * g.matrix_bytes(n))?;

    let mut mats: Vec<Option<DeviceMatrix>> = Vec::with_capacity(buffers as usize);
    mats.push(Some(g.upload("F", n, &fp)?.0));
    drop(fp);
    mats.push(Some(g.upload("Q = F diag(rho)", n, &q)?.0));
    drop(q);
    const F: usize = 0;
    const Q: usize = 1;
    let mut free: Vec<usize> = Vec::new();
    let skip = options.skip_zero_tiles;

    // out = d + a·b into a free buffer; returns its slot.
    let product = |mats: &mut Vec<Option<DeviceMatrix>>,
                   free: &mut Vec<usize>,
                   cs: &mut ChannelStats,
                   a: usize,
                   b: usize,
                   d: Option<usize>,
                   what: &str|
     -> Result<(usize, GemmRun), BakeError> {
        let slot = match free.pop() {
            Some(s) => s,
            None => {
                mats.push(Some(g.alloc("transfer product", n)?));
                mats.len() - 1
            }
        };
        let mut out = mats[slot].take().expect("a free slot holds a buffer");
        let get = |i: usize| mats[i].as_ref().expect("operand present");
        let run = g.multiply(get(a), get(b), d.map(get), &mut out, skip);
        mats[slot] = Some(out);
        let run = run?;
        cs.gemms += 1;
        cs.tile_products += run.tile_products;
        cs.skipped_tiles += run.skipped;
        cs.seconds_gemm += run.seconds;
        cs.gflop += run.flops * 1e-9;
        if run.nonfinite() {
            return Err(BakeError::Numeric {
                stage: STAGE,
                detail: format!(
                    "a non-finite value appeared in channel {name} at {what} (spectral bound \
                     max_i rho_i sum_j F_ij = {:.6}): the series diverges",
                    cs.spectral_bound
                ),
            });
        }
        Ok((slot, run))
    };
    let protected = |s: usize| keep && (s == F || s == Q);

    let mut t = F;
    let mut qm = Q;
    let mut terms: u64 = 1;
    let mut converged = false;
    for d in 1..=doublings_planned {
        // T_2m = T_m + Q^m T_m.
        let (out, run) = product(
            &mut mats,
            &mut free,
            cs,
            qm,
            t,
            Some(t),
            &format!("doubling {d}"),
        )?;
        tick(options.bounces == Bounces::Infinite);
        if !protected(t) {
            free.push(t);
        }
        t = out;
        terms *= 2;
        cs.doublings = d;
        cs.last_term_ratio = run.max_term_ratio;
        if options.bounces == Bounces::Infinite && run.max_term_ratio <= CONVERGED_RATIO {
            converged = true;
            break;
        }
        if d == doublings_planned {
            break;
        }
        // Q^2m = Q^m Q^m.
        let (out, _) = product(
            &mut mats,
            &mut free,
            cs,
            qm,
            qm,
            None,
            &format!("squaring {d}"),
        )?;
        tick(options.bounces == Bounces::Infinite);
        if !protected(qm) {
            free.push(qm);
        }
        qm = out;
    }
    if options.bounces == Bounces::Infinite && !converged {
        return Err(BakeError::Mismatch {
            stage: STAGE,
            detail: format!(
                "the infinite series did not converge in channel {name} after {MAX_DOUBLINGS} \
                 doublings (2^{MAX_DOUBLINGS} bounces; last term / sum = {:.3e}, spectral bound \
                 {:.6})",
                cs.last_term_ratio, cs.spectral_bound
            ),
        });
    }
    for h in 1..=horner_steps {
        // T_{m+1} = F + Q T_m.
        let (out, run) = product(
            &mut mats,
            &mut free,
            cs,
            Q,
            t,
            Some(F),
            &format!("Horner step {h}"),
        )?;
        tick(false);
        if !protected(t) {
            free.push(t);
        }
        t = out;
        terms += 1;
        cs.horner_steps = h;
        cs.last_term_ratio = run.max_term_ratio;
    }
    cs.terms = terms;
    let tp = g.download("T", mats[t].as_ref().expect("result present"))?;
    if let Some(e) = tp.iter().position(|x| !x.is_finite()) {
        // The products' epilogues catch this first; kept as a last guard.
        return Err(BakeError::Numeric {
            stage: STAGE,
            detail: format!("non-finite T entry {e} in channel {name}"),
        });
    }
    if !permuted {
        return Ok(tp);
    }
    let mut out = vec![0.0f32; n * n];
    for (a, &i) in order.iter().enumerate() {
        for (b, &j) in order.iter().enumerate() {
            out[i * n + j] = tp[a * n + b];
        }
    }
    Ok(out)
}

/// The f64 CPU reference for one channel with albedos `rho`: `T_k` by
/// Horner with dense products (`T_{h+1} = F + F diag(ρ) T_h`), `T_∞` by an
/// LU solve of `X (I − diag(ρ) F) = F` (faer, partial pivoting).
pub fn reference(
    f: &[f32],
    n: usize,
    rho: &[f64],
    bounces: Bounces,
) -> Result<Vec<f64>, BakeError> {
    use crate::gemm::to_faer;
    assert_eq!(rho.len(), n);
    let fm = to_faer(f, n, f64::from);
    let par = faer::Par::rayon(0);
    let t = match bounces {
        Bounces::K(0) => {
            return Err(BakeError::InvalidOption {
                option: "bounces",
                value: "0".into(),
                expected: "at least 1, or infinite".into(),
            })
        }
        Bounces::K(k) => {
            let q = faer::Mat::from_fn(n, n, |i, j| fm[(i, j)] * rho[j]);
            let mut t = fm.clone();
            for _ in 1..k {
                let mut next = fm.clone();
                faer::linalg::matmul::matmul(
                    next.as_mut(),
                    faer::Accum::Add,
                    q.as_ref(),
                    t.as_ref(),
                    1.0,
                    par,
                );
                t = next;
            }
            t
        }
        Bounces::Infinite => {
            let m = faer::Mat::from_fn(n, n, |i, j| f64::from(i == j) - rho[i] * fm[(i, j)]);
            m.partial_piv_lu().rsolve(fm.as_ref())
        }
    };
    Ok((0..n * n).map(|e| t[(e / n, e % n)]).collect())
}
