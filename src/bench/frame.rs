//! `radiosity bench frame`: the CPU run time's frame, stage by stage, and
//! classic radiosity measured in the same run as the baseline.
//!
//! - **Memory bandwidth**: a STREAM-like triad `a = b + s c` over three
//!   arrays of 2^25 f32 (128 MiB each, far above the caches), on all
//!   threads, counting 12 bytes per element; the best of a few runs.
//! - **The run time**: a full frame without reuse (direct light, gathers),
//!   the gather alone over every column and over the lights' active
//!   columns (bytes of compressed matrix read per second, as a fraction of
//!   the bandwidth; decoded entries per second per thread), an unchanged
//!   frame, and the CPU renderer at the stated resolution.
//! - **Classic radiosity** (the honest baseline): `F` computed again from
//!   the bake's own options (the same patches, permuted into matrix
//!   order), held as f32; one pass per bounce reads `F` once and updates
//!   all three channels (`y_c = F x_c`, `H += y`, `x_c = ρ_c ∘ y_c`),
//!   multithreaded over rows and vectorised by hand (AVX-512 where the
//!   CPU has it, else AVX2 with FMA, as the gather; six accumulators). k = 1, 2, 3 bounces per frame, and for the
//!   infinite-bounce limit Jacobi iterations until its error is at most the
//!   compressed `T̃`'s.
//! - **Errors** are against the exact `H = T_∞ B0` of the same `F`, itself
//!   Jacobi-iterated in f64 until the update is below 1e-10 of `H`.

pub use super::{best, rel_rms};
use super::{fma_peak, keep_fastest, memory_bandwidth_triad};
use crate::bake::form_factor::{of_voxelization, FormFactorOptions};
use crate::bake::voxelize::voxelize_at;
use crate::core::compute::{Backend, DeviceSelection, Gpu};
use crate::core::scene_config::SceneConfig;
use crate::runtime::gather::{ActiveColumns, GatherStats};
use crate::runtime::render::{render, View};
use crate::runtime::texture::Albedo;
use crate::runtime::{Runtime, RuntimeOptions};
use anyhow::Context as _;
use rayon::prelude::*;
use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

/// What the benchmark measures.
pub struct FrameBenchOptions {
    pub repeat: usize,
    pub width: usize,
    pub height: usize,
    pub selection: DeviceSelection,
    /// Skip the classic baseline (it recomputes `F`).
    pub classic: bool,
}

/// [`best`] of two functions whose times are compared: runs alternate, so
/// that a burst of load from other jobs on a shared machine falls on both
/// rather than on whichever ran during it. Short runs repeat beyond
/// `repeat` until [`ALTERNATING_BUDGET_S`] has passed (at most
/// [`ALTERNATING_MAX`] pairs): the more samples of a millisecond-long
/// run, the likelier its fastest is one that no other job disturbed.
pub(crate) fn best_alternating<A, B>(
    repeat: usize,
    mut f: impl FnMut() -> A,
    mut g: impl FnMut() -> B,
) -> ((A, f64), (B, f64)) {
    let mut bf: Option<(A, f64)> = None;
    let mut bg: Option<(B, f64)> = None;
    let start = Instant::now();
    for i in 0.. {
        if i >= repeat.max(1)
            && (start.elapsed().as_secs_f64() >= ALTERNATING_BUDGET_S || i >= ALTERNATING_MAX)
        {
            break;
        }
        keep_fastest(&mut bf, &mut f);
        keep_fastest(&mut bg, &mut g);
    }
    (bf.expect("at least one run"), bg.expect("at least one run"))
}

/// Seconds [`best_alternating`] spends at least, repeating short runs.
const ALTERNATING_BUDGET_S: f64 = 0.5;

/// Pairs [`best_alternating`] runs at most beyond `repeat`.
const ALTERNATING_MAX: usize = 200;

/// One pass of classic radiosity: `y_c = F x_c` for the three channels,
/// reading `F` once (module doc).
pub fn classic_pass(f: &[f32], n: usize, x: &[Vec<f32>; 3], y: &mut [Vec<f32>; 3]) {
    // The widest vector unit the CPU reports (simd_kind: "avx512",
    // "avx2" or "none"), chosen once.
    let simd = crate::runtime::gather::simd_kind();
    let rows: Vec<[f32; 3]> = (0..n)
        .into_par_iter()
        .map(|i| {
            let row = &f[i * n..(i + 1) * n];
            #[cfg(target_arch = "x86_64")]
            match simd {
                // SAFETY: AVX-512F reported by the CPU.
                "avx512" => return unsafe { dot3_avx512(row, x) },
                // SAFETY: AVX2 and FMA reported by the CPU.
                "avx2" => return unsafe { dot3_avx2(row, x) },
                _ => {}
            }
            let _ = simd;
            dot3(row, x)
        })
        .collect();
    for (i, r) in rows.iter().enumerate() {
        for c in 0..3 {
            y[c][i] = r[c];
        }
    }
}

/// Three dot products of one row, 16 partial sums each (vectorises).
#[inline(always)]
fn dot3(row: &[f32], x: &[Vec<f32>; 3]) -> [f32; 3] {
    let mut acc = [[0.0f32; 16]; 3];
    let chunks = row.len() / 16;
    for k in 0..chunks {
        let r = &row[16 * k..16 * k + 16];
        for c in 0..3 {
            let xs = &x[c][16 * k..16 * k + 16];
            for l in 0..16 {
                acc[c][l] += r[l] * xs[l];
            }
        }
    }
    let mut out = acc.map(|a| a.iter().sum::<f32>());
    for j in 16 * chunks..row.len() {
        for c in 0..3 {
            out[c] += row[j] * x[c][j];
        }
    }
    out
}

/// A hand-vectorised [`dot3`] (`$lanes`-wide vectors of the named target
/// feature): per `2 $lanes` entries of the row two loads of `F`, six of
/// `x` and six fused multiply-adds into six accumulators (two per channel,
/// so that no add waits on the previous one's latency); the lanes summed
/// pairwise at the end, the tail in scalar code. Left to the compiler,
/// `dot3` became 128-bit shuffles with the accumulators spilled and no
/// FMA, about 4× slower (2.2e9 against 8–9e9 entries/s on 2 threads): the
/// baseline would have been a straw man.
macro_rules! dot3_kernel {
    ($name:ident, $feature:literal, $lanes:literal, $vec:ty, $zero:ident, $load:ident, $fmadd:ident, $add:ident, $store:ident) => {
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = $feature)]
        unsafe fn $name(row: &[f32], x: &[Vec<f32>; 3]) -> [f32; 3] {
            use std::arch::x86_64::*;
            let n = row.len().min(x[0].len()).min(x[1].len()).min(x[2].len());
            let (r, x0, x1, x2) = (row.as_ptr(), x[0].as_ptr(), x[1].as_ptr(), x[2].as_ptr());
            let mut a: [$vec; 6] = [$zero(); 6];
            let pairs = n / (2 * $lanes);
            for k in 0..pairs {
                for h in 0..2 {
                    let o = 2 * $lanes * k + $lanes * h;
                    let f = $load(r.add(o));
                    a[h] = $fmadd(f, $load(x0.add(o)), a[h]);
                    a[2 + h] = $fmadd(f, $load(x1.add(o)), a[2 + h]);
                    a[4 + h] = $fmadd(f, $load(x2.add(o)), a[4 + h]);
                }
            }
            let mut out = [0.0f32; 3];
            for (c, o) in out.iter_mut().enumerate() {
                let mut l = [0.0f32; $lanes];
                $store(l.as_mut_ptr(), $add(a[2 * c], a[2 * c + 1]));
                let mut w = $lanes;
                while w > 1 {
                    w /= 2;
                    for i in 0..w {
                        l[i] += l[i + w];
                    }
                }
                *o = l[0];
            }
            for j in 2 * $lanes * pairs..n {
                for (c, o) in out.iter_mut().enumerate() {
                    *o += row[j] * x[c][j];
                }
            }
            out
        }
    };
}

dot3_kernel!(
    dot3_avx512,
    "avx512f",
    16,
    __m512,
    _mm512_setzero_ps,
    _mm512_loadu_ps,
    _mm512_fmadd_ps,
    _mm512_add_ps,
    _mm512_storeu_ps
);
dot3_kernel!(
    dot3_avx2,
    "avx2,fma",
    8,
    __m256,
    _mm256_setzero_ps,
    _mm256_loadu_ps,
    _mm256_fmadd_ps,
    _mm256_add_ps,
    _mm256_storeu_ps
);

/// `f` (n × n, patch order) with row and column `i` taken from patch
/// `order[i]`: the matrix order of a bake's run time.
pub(crate) fn in_matrix_order(f: &[f32], n: usize, order: &[u32]) -> Vec<f32> {
    let mut out = vec![0.0f32; n * n];
    out.par_chunks_mut(n).enumerate().for_each(|(i, row)| {
        let src = &f[order[i] as usize * n..(order[i] as usize + 1) * n];
        for (j, v) in row.iter_mut().enumerate() {
            *v = src[order[j] as usize];
        }
    });
    out
}

/// `k` bounces of classic radiosity from `b0` (module doc).
pub fn classic(
    f: &[f32],
    n: usize,
    albedo: &[[f32; 3]],
    b0: &[Vec<f32>; 3],
    k: usize,
) -> [Vec<f32>; 3] {
    let mut x = b0.clone();
    let mut y: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0; n]);
    let mut h: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0; n]);
    for _ in 0..k {
        classic_pass(f, n, &x, &mut y);
        for c in 0..3 {
            for j in 0..n {
                h[c][j] += y[c][j];
                x[c][j] = albedo[j][c] * y[c][j];
            }
        }
    }
    h
}

/// The exact `H = T_∞ B0` of `F` (module doc), in f64.
pub fn exact_infinite(
    f: &[f32],
    n: usize,
    albedo: &[[f32; 3]],
    b0: &[Vec<f32>; 3],
) -> [Vec<f64>; 3] {
    exact_series(f, n, albedo, b0, None)
}

/// The exact `H` of `k` bounces of `F` in f64, `Σ_{h=1..k} F (ρF)^{h−1}
/// B0`; `None`: until the next term is below 1e-10 of the sum (`T_∞`).
pub fn exact_series(
    f: &[f32],
    n: usize,
    albedo: &[[f32; 3]],
    b0: &[Vec<f32>; 3],
    k: Option<usize>,
) -> [Vec<f64>; 3] {
    std::array::from_fn(|c| {
        let mut h = vec![0.0f64; n];
        let mut x: Vec<f64> = b0[c].iter().map(|&v| v as f64).collect();
        for _ in 0..k.unwrap_or(100_000) {
            let y: Vec<f64> = (0..n)
                .into_par_iter()
                .map(|i| {
                    f[i * n..(i + 1) * n]
                        .iter()
                        .zip(&x)
                        .map(|(&a, &b)| a as f64 * b)
                        .sum()
                })
                .collect();
            let (mut dy, mut sh) = (0.0f64, 0.0f64);
            for j in 0..n {
                h[j] += y[j];
                dy += y[j] * y[j];
                sh += h[j] * h[j];
                x[j] = albedo[j][c] as f64 * y[j];
            }
            if k.is_none() && dy <= 1e-20 * sh {
                break;
            }
        }
        h
    })
}

/// A frame's times ([`time_frame`]).
pub(crate) struct FrameTimes {
    pub stats: crate::runtime::FrameStats,
    /// Seconds of the whole frame.
    pub frame: f64,
    pub b0: [Vec<f32>; 3],
    /// `T̃ · B0` of the frame's `B0`: the compressed gather alone, without
    /// the near-field correction the frame's `H` adds, so that it can be
    /// compared with the exact `T B0` of the same `F` (the codec's error).
    pub h: [Vec<f32>; 3],
    pub all: ActiveColumns,
    pub lit: ActiveColumns,
    /// The gather alone over every column and over the lit ones: what it
    /// read, and seconds.
    pub gather_all: (GatherStats, f64),
    pub gather_lit: (GatherStats, f64),
}

/// A full frame of `config`'s lights with nothing reused (`rt` must not
/// cache), then the gather alone over every column and over the frame's
/// active ones; the fastest of `repeat` runs each.
pub(crate) fn time_frame(rt: &mut Runtime, config: &SceneConfig, repeat: usize) -> FrameTimes {
    let lights = config.frame_lights();
    let (stats, frame) = best(repeat, || rt.frame(&lights, &config.emission));
    let b0 = rt.b0().clone();
    let (h, _, _) = rt.product(&b0);
    let refs = [&b0[0][..], &b0[1][..], &b0[2][..]];
    let tile = rt.baked.matrix.index.tile;
    let all = ActiveColumns::of(refs, tile, true);
    let lit = ActiveColumns::of(refs, tile, false);
    let (mut s1, mut s2) = (h.clone(), h.clone());
    let (gather_all, gather_lit) = best_alternating(
        repeat,
        || rt.gather.gather(refs, &all, &mut s1),
        || rt.gather.gather(refs, &lit, &mut s2),
    );
    FrameTimes {
        stats,
        frame,
        b0,
        h,
        all,
        lit,
        gather_all,
        gather_lit,
    }
}

/// Runs the benchmark on the bake at `path` with `config`'s camera and
/// lights; returns the Markdown report.
pub fn run(
    path: &Path,
    config: &SceneConfig,
    options: &FrameBenchOptions,
) -> anyhow::Result<String> {
    let mut out = String::new();
    // The bake and the scene it was made from, checked to be that scene.
    let (baked, scene, _) = crate::runtime::open::load_checked(path, None)?;
    let n = baked.patches.len();
    let bytes_matrix = baked.matrix.bytes_total();
    writeln!(
        out,
        "## {} ({} patches, codec {}, {:.3} bytes per entry, {} bytes)\n",
        path.display(),
        n,
        baked.matrix.kind.name(),
        baked.matrix.bytes_per_entry(),
        bytes_matrix
    )?;
    let bandwidth = memory_bandwidth_triad();
    let threads = rayon::current_num_threads();
    writeln!(
        out,
        "memory bandwidth (STREAM-like triad, {threads} threads): {:.2} GB/s; vectorised BC1 gather: {}\n",
        bandwidth / 1e9,
        crate::runtime::gather::simd_kind()
    )?;

    let albedo_tex = Albedo::new(&scene);
    let mut rt = Runtime::new(
        baked,
        scene,
        RuntimeOptions {
            cache: false,
            ..RuntimeOptions::default()
        },
    );
    // The sky's cost: the same frame without it, then with it (the sky
    // term: `D_sky` from the sky's cells and one more gather).
    let sky_cost = match &config.sky {
        None => None,
        Some(sky) => {
            rt.set_sky(None).expect("no sky is always accepted");
            let (_, without) = best(options.repeat, || {
                rt.frame(&config.frame_lights(), &config.emission)
            });
            rt.set_sky(Some(sky.clone()))
                .context("the camera-and-lights file has a sky")?;
            let t0 = std::time::Instant::now();
            let cells = sky.cell_radiance();
            let t_cells = t0.elapsed().as_secs_f64();
            drop(cells);
            Some((without, t_cells))
        }
    };
    let ft = time_frame(&mut rt, config, options.repeat);
    let (fs, t_frame, b0, h_rt) = (ft.stats, ft.frame, ft.b0, ft.h);
    let refs = [&b0[0][..], &b0[1][..], &b0[2][..]];
    let tile = rt.baked.matrix.index.tile;
    let (all, lit) = (ft.all, ft.lit);
    let mut h = h_rt.clone();
    let ((s_all, t_all), (s_lit, t_lit)) = (ft.gather_all, ft.gather_lit);
    // Unchanged frame.
    rt.options.cache = true;
    let lights = config.frame_lights();
    rt.frame(&lights, &config.emission);
    let (fu, t_unchanged) = best(options.repeat, || rt.frame(&lights, &config.emission));
    assert!(fu.unchanged);
    // Rendering.
    let (_, t_render) = best(1, || {
        render(
            &rt,
            config,
            View::Final,
            options.width,
            options.height,
            &albedo_tex,
        )
    });

    writeln!(out, "| stage | time | notes |")?;
    writeln!(out, "|---|---|---|")?;
    writeln!(
        out,
        "| frame, nothing reused | {:.2} ms | direct {:.2} ms ({} lights, {} samples per patch), near-field correction {:.3} ms ({} links), gathers {:.2} ms, every probe {:.3} ms |",
        1e3 * t_frame,
        1e3 * fs.seconds_direct,
        lights.len(),
        rt.options.samples,
        1e3 * fs.seconds_near_field,
        rt.near.links(),
        1e3 * fs.seconds_gather,
        1e3 * fs.seconds_probes
    )?;
    if let (Some((without, t_cells)), Some(sky)) = (sky_cost, &config.sky) {
        writeln!(
            out,
            "| the sky ({}) | +{:.2} ms | the frame above against {:.2} ms without the sky: its cells' mean radiance {:.2} ms (on a sky change), `D_sky` and one more gather |",
            sky.kind(),
            1e3 * (t_frame - without),
            1e3 * without,
            1e3 * t_cells
        )?;
    }
    let gb = |s: &crate::runtime::gather::GatherStats, t: f64| s.bytes_read as f64 / t;
    writeln!(
        out,
        "| gather, every column | {:.3} ms | {:.2} GB/s read = {:.1} % of bandwidth; {:.2e} entries/s/thread |",
        1e3 * t_all,
        gb(&s_all, t_all) / 1e9,
        100.0 * gb(&s_all, t_all) / bandwidth,
        s_all.entries as f64 / t_all / threads as f64
    )?;
    writeln!(
        out,
        "| gather, lit columns ({:.1} % active) | {:.3} ms | {:.2}× faster than every column; {:.2} GB/s |",
        100.0 * lit.active_groups as f64 / all.active_groups.max(1) as f64,
        1e3 * t_lit,
        t_all / t_lit,
        gb(&s_lit, t_lit) / 1e9
    )?;
    // The probes' update, as a changed frame runs it after the terms.
    if !rt.baked.probes.is_empty() {
        let (_, t_probes) = best(options.repeat, || rt.update_probes(None));
        let pr = &rt.baked.probes;
        let used = pr.states.iter().filter(|s| s.is_used()).count();
        let entries = pr.patches.len() + pr.sky_cells.len();
        writeln!(
            out,
            "| probe update, every probe ({} probes, {used} used, {} patch and {} sky entries) | {:.3} ms | {:.1} % of the every-column gather, {:.1} % of the lit-column one; {:.2e} entries/s |",
            pr.len(),
            pr.patches.len(),
            pr.sky_cells.len(),
            1e3 * t_probes,
            100.0 * t_probes / t_all,
            100.0 * t_probes / t_lit,
            entries as f64 / t_probes
        )?;
        // The probes one moving object reads: a sphere of one probe
        // spacing's diameter at the camera's target.
        let c = config.camera.target.map(f64::from);
        let r = 0.5 * f64::from(pr.grid.spacing);
        let which = crate::runtime::probes::needed(&pr.grid, c.map(|v| v - r), c.map(|v| v + r));
        let k = which.len();
        let (_, t_one) = best(options.repeat, || rt.update_probes(Some(&which)));
        writeln!(
            out,
            "| probe update, the {k} probes one object reads (a {:.2}-unit sphere at the camera's target) | {:.3} ms | {:.1} % of the every-column gather, {:.1} % of the lit-column one |",
            2.0 * r,
            1e3 * t_one,
            100.0 * t_one / t_all,
            100.0 * t_one / t_lit
        )?;
    }
    // One spot light lighting at most 10 % of the patches: from the camera
    // towards its target, the cone narrowed until it does.
    let cam = &config.camera;
    let axis: [f32; 3] = std::array::from_fn(|k| cam.target[k] - cam.position[k]);
    let mut cone = 40.0f32;
    let mut spot_b0 = None;
    for _ in 0..16 {
        let light = crate::core::scene_config::Light::Spot {
            position: cam.position,
            direction: axis,
            intensity: [1.0; 3],
            cone_angle_deg: cone,
            beam_angle_deg: 0.5 * cone,
        };
        let (d_points, d) = crate::runtime::direct::irradiance(
            &rt.baked,
            &rt.direct,
            std::slice::from_ref(&light),
            rt.options.samples,
        );
        let lit = (0..n).filter(|&j| d.iter().any(|c| c[j] > 0.0)).count();
        if lit <= n / 10 && lit > 0 {
            let b0 = crate::runtime::direct::reflected(&rt.baked, &d);
            spot_b0 = Some((b0, d_points, lit, cone));
            break;
        }
        cone *= if lit == 0 { 1.3 } else { 0.7 };
    }
    writeln!(
        out,
        "| unchanged frame | {:.4} ms | nothing recomputed |",
        1e3 * t_unchanged
    )?;
    // The spot's CPU gathers are timed before any GL work, so that no GL
    // thread can run beside them (moving them here changed nothing
    // measurable on the 2-core host, but no GL state is left to doubt).
    let mut spot_row = String::new();
    if let Some((sb0, spot_points, lit_patches, cone)) = &spot_b0 {
        let (lit_patches, cone) = (*lit_patches, *cone);
        let sr = [&sb0[0][..], &sb0[1][..], &sb0[2][..]];
        let sall = ActiveColumns::of(sr, tile, true);
        let slit = ActiveColumns::of(sr, tile, false);
        let mut h2 = h.clone();
        let ((_, ts_all), (ss, ts_lit)) = best_alternating(
            options.repeat,
            || rt.gather.gather(sr, &sall, &mut h),
            || rt.gather.gather(sr, &slit, &mut h2),
        );
        writeln!(
            spot_row,
            "| gather, one spot light ({cone:.1}° cone, {:.1} % of patches lit, {:.1} % of column groups) | {:.3} ms | {:.2}× faster than every column ({:.3} ms); {:.2} GB/s |",
            100.0 * lit_patches as f64 / n as f64,
            100.0 * slit.active_groups as f64 / sall.active_groups.max(1) as f64,
            1e3 * ts_lit,
            ts_all / ts_lit,
            1e3 * ts_all,
            gb(&ss, ts_lit) / 1e9
        )?;
        // The same light with negligible columns culled at the viewer's
        // default: its time against the every-column gather, and the
        // error it adds against the exact spot product just timed.
        let eps = crate::runtime::VIEWER_CULL;
        let t0 = Instant::now();
        let weights = rt.column_weights();
        let t_weights = t0.elapsed().as_secs_f64();
        let culled = ActiveColumns::culled(sr, tile, weights, eps);
        let mut h3 = h2.clone();
        let ((_, tc_all), (_, tc_lit)) = best_alternating(
            options.repeat,
            || rt.gather.gather(sr, &sall, &mut h),
            || rt.gather.gather(sr, &culled.columns, &mut h3),
        );
        let (rms, l1, norm) = relative_errors(&h2, &h3);
        writeln!(
            spot_row,
            "| that spot light, negligible columns culled (ε = {eps}: {:.1} % of column groups, {} dropped; `T̃`'s column sums {:.1} ms, once) | {:.3} ms | {:.2}× faster than every column ({:.3} ms); H against the exact product: {:.3} % RMS, {:.4} % L1 (bound {:.4} %) |",
            100.0 * culled.columns.active_groups as f64 / sall.active_groups.max(1) as f64,
            culled.culled_groups,
            1e3 * t_weights,
            1e3 * tc_lit,
            tc_all / tc_lit,
            1e3 * tc_all,
            100.0 * rms,
            100.0 * l1,
            100.0 * culled.dropped_mass / norm.max(f64::MIN_POSITIVE),
        )?;
        // What a frame computes for that light: with the bake's near-field
        // correction, `c` and `δ` from its lit points and the gather of
        // `B0 + δ + ρ ∘ c`, whose `ρ ∘ c` lights the lit patches'
        // neighbours' columns too.
        if !rt.near.is_empty() {
            let ((_, tf_all), ((_, _, groups), tf_lit)) = best_alternating(
                options.repeat,
                || rt.light_product_over(sb0, spot_points, true),
                || rt.light_product_over(sb0, spot_points, false),
            );
            writeln!(
                spot_row,
                "| that spot light's term as a frame computes it (near-field correction, then the gather of B0 + δ + ρ∘c: {:.1} % of column groups) | {:.3} ms | {:.2}× faster than over every column ({:.3} ms) |",
                100.0 * groups as f64 / sall.active_groups.max(1) as f64,
                1e3 * tf_lit,
                tf_all / tf_lit,
                1e3 * tf_all,
            )?;
            // The frame's term with culling, as the viewer runs it.
            let (h_exact, _, _) = rt.light_product_over(sb0, spot_points, false);
            rt.options.cull = eps;
            let ((_, tg_all), ((h_cull, st, groups), tg_lit)) = best_alternating(
                options.repeat,
                || rt.light_product_over(sb0, spot_points, true),
                || rt.light_product_over(sb0, spot_points, false),
            );
            rt.options.cull = 0.0;
            let (rms, l1, norm) = relative_errors(&h_exact, &h_cull);
            writeln!(
                spot_row,
                "| that term with negligible columns culled (ε = {eps}: {:.1} % of column groups, {} dropped) | {:.3} ms | {:.2}× faster than over every column ({:.3} ms); H against the exact term: {:.3} % RMS, {:.4} % L1 (bound {:.4} %) |",
                100.0 * groups as f64 / sall.active_groups.max(1) as f64,
                st.culled_groups,
                1e3 * tg_lit,
                tg_all / tg_lit,
                1e3 * tg_all,
                100.0 * rms,
                100.0 * l1,
                100.0 * st.culled_mass / norm.max(f64::MIN_POSITIVE),
            )?;
        }
    }
    out.push_str(&spot_row);
    writeln!(
        out,
        "| CPU render {}×{} (final view: rays, shadows, surface map, shading) | {:.1} ms | |",
        options.width,
        options.height,
        1e3 * t_render
    )?;
    // The two roofs of the every-column gather: memory (the triad) and
    // arithmetic (one multiply-add per position and channel, against the
    // FMA peak measured now). Where the FMA roof lies below a fraction of
    // the triad, no decoder on these cores reaches that fraction.
    let lane_fmas = 3.0 * s_all.entries as f64 / t_all;
    match fma_peak() {
        Some(peak) => {
            let cap = peak * s_all.bytes_read as f64 / (3.0 * s_all.entries.max(1) as f64);
            writeln!(
                out,
                "\nroofs of the every-column gather on {threads} threads: memory {:.1} % of the triad; \
                 arithmetic {:.2e} of the measured {:.2e} lane FMAs/s ({:.1} %, 3 per position). \
                 Multiply-adds alone, at the FMA peak, would read {:.2} GB/s = {:.0} % of the triad",
                100.0 * gb(&s_all, t_all) / bandwidth,
                lane_fmas,
                peak,
                100.0 * lane_fmas / peak,
                cap / 1e9,
                100.0 * cap / bandwidth
            )?;
        }
        None => writeln!(
            out,
            "
roofs of the every-column gather: memory {:.1} % of the triad; {:.2e} lane FMAs/s (no AVX2 + FMA: no FMA peak measured)",
            100.0 * gb(&s_all, t_all) / bandwidth,
            lane_fmas
        )?,
    }
    // The GPU half (src/bench/frame_gl.rs), after every CPU timing above,
    // so that no GL thread runs beside them.
    let gl_ctx = crate::gl::context::Headless::new();
    let gl_gather = match &gl_ctx {
        Ok(ctx) => {
            let t = super::frame_gl::gather_table(
                &mut out,
                ctx,
                &rt,
                refs,
                &all,
                &lit,
                &h_rt,
                options.repeat,
            )?;
            super::frame_gl::frame_table(
                &mut out,
                ctx,
                &rt,
                config,
                (options.width, options.height),
                options.repeat,
                t_frame,
            )?;
            t
        }
        Err(e) => {
            writeln!(out, "\nGL gather and frame not run: {e}")?;
            None
        }
    };

    if !options.classic {
        return Ok(out);
    }
    // Classic radiosity on the same patches.
    let gpu = Gpu::new(options.selection).context("opening the OpenCL device")?;
    let backend = Backend::OpenCl(&gpu);
    let vox = voxelize_at(&rt.scene, rt.baked.options.voxel_size, &backend)?;
    let ffo = FormFactorOptions {
        method: crate::bake::form_factor::FormFactorMethod::parse(&rt.baked.options.ff_method)
            .context("the bake's form-factor method")?,
        rays_per_patch: rt.baked.options.ff_rays_per_patch,
        samples: rt.baked.options.ff_samples,
        rays: rt.baked.options.ff_rays,
        quadrature_tol: rt.baked.options.ff_quadrature_tol,
        ..FormFactorOptions::default()
    };
    let ff = of_voxelization(&rt.scene, &vox, &ffo, &backend, &mut |_, _| {})?;
    anyhow::ensure!(
        ff.n == n,
        "the form factors recomputed from the bake's options keep {} patches, the bake {n}",
        ff.n
    );
    // Into matrix order: row/column i is file patch order[i].
    let f = in_matrix_order(&ff.f, n, &rt.baked.order);
    let albedo: Vec<[f32; 3]> = rt.baked.patches.iter().map(|p| p.albedo).collect();
    let exact = exact_infinite(&f, n, &albedo, &b0);
    let err_gather = rel_rms(&h_rt, &exact);
    writeln!(
        out,
        "\nclassic radiosity on the same {n} patches (F recomputed: {:.1} s; {} bytes as f32, {:.0}× the compressed matrix); errors against the exact T_∞ B0 of that F\n",
        ff.stats.seconds_total,
        4 * n * n,
        (4 * n * n) as f64 / bytes_matrix as f64
    )?;
    writeln!(
        out,
        "| method | time per frame | rel. RMS error of H | gather's speed-up |"
    )?;
    writeln!(out, "|---|---|---|---|")?;
    writeln!(
        out,
        "| compressed T̃_∞ gather (lit columns) | {:.3} ms | {:.3} % | 1 |",
        1e3 * t_lit,
        100.0 * err_gather
    )?;
    let mut t_classic = Vec::new();
    for k in 1..=3 {
        let (hk, t) = best(options.repeat, || classic(&f, n, &albedo, &b0, k));
        t_classic.push(t);
        writeln!(
            out,
            "| classic, {k} bounce{} | {:.3} ms | {:.3} % | {:.1}× |",
            if k > 1 { "s" } else { "" },
            1e3 * t,
            100.0 * rel_rms(&hk, &exact),
            t / t_lit
        )?;
    }
    // Classic ∞: the fewest bounces reaching the gather's error.
    let mut k = 3;
    let mut hk = classic(&f, n, &albedo, &b0, k);
    while rel_rms(&hk, &exact) > err_gather && k < 10_000 {
        k += 1;
        hk = classic(&f, n, &albedo, &b0, k);
    }
    let (hk, t) = best(options.repeat, || classic(&f, n, &albedo, &b0, k));
    writeln!(
        out,
        "| classic ∞ (Jacobi, {k} passes to reach the gather's error) | {:.3} ms | {:.3} % | {:.1}× |",
        1e3 * t,
        100.0 * rel_rms(&hk, &exact),
        t / t_lit
    )?;
    t_classic.push(t);
    if let Ok(ctx) = &gl_ctx {
        super::frame_gl::classic_rows(
            &mut out,
            ctx,
            &f,
            n,
            &albedo,
            &b0,
            &exact,
            k,
            gl_gather,
            options.repeat,
        )?;
    }
    // The same lights' gather with negligible columns culled at the
    // viewer's default, against the same classic times: its error is
    // measured against the same exact `T_∞ B0`, so the comparison stays
    // at a stated error.
    let eps = crate::runtime::VIEWER_CULL;
    let refs = [&b0[0][..], &b0[1][..], &b0[2][..]];
    let culled = ActiveColumns::culled(refs, tile, rt.column_weights(), eps);
    let mut hc = h_rt.clone();
    let (_, t_cull) = best(options.repeat, || {
        rt.gather.gather(refs, &culled.columns, &mut hc)
    });
    writeln!(
        out,
        "\nthe scene's lights gathered with negligible columns culled (ε = {eps}: {:.1} % of column groups, against {:.1} % lit): {:.3} ms, {:.3} % error against the same T_∞ B0; classic 1, 2, 3 bounces and ∞ to the exact gather's error {} slower",
        100.0 * culled.columns.active_groups as f64 / all.active_groups.max(1) as f64,
        100.0 * lit.active_groups as f64 / all.active_groups.max(1) as f64,
        1e3 * t_cull,
        100.0 * rel_rms(&hc, &exact),
        t_classic
            .iter()
            .map(|t| format!("{:.1}×", t / t_cull))
            .collect::<Vec<_>>()
            .join(", ")
    )?;
    Ok(out)
}

/// `b`'s relative RMS and L1 differences from `a` over every patch and
/// channel (0 where `a` is all zero), and `a`'s L1 norm: culling's bound
/// on the L1 difference, over that norm, is the bound on the relative L1
/// difference (the bound's own total `E` differs from `‖a‖₁` where the
/// input has negative values, as `δ` does, or `c` is added after).
fn relative_errors(a: &[Vec<f32>; 3], b: &[Vec<f32>; 3]) -> (f64, f64, f64) {
    let (mut d2, mut a2, mut d1, mut a1) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for (ac, bc) in a.iter().zip(b) {
        for (&x, &y) in ac.iter().zip(bc) {
            let d = f64::from(y) - f64::from(x);
            d2 += d * d;
            a2 += f64::from(x) * f64::from(x);
            d1 += d.abs();
            a1 += f64::from(x).abs();
        }
    }
    let ratio = |d: f64, a: f64| if a > 0.0 { d / a } else { 0.0 };
    (ratio(d2.sqrt(), a2.sqrt()), ratio(d1, a1), a1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::math::SplitMix64;

    /// The classic pass (the vector kernel this CPU runs) and the portable
    /// `dot3` against an f64 product, on a size that leaves a tail. Bound
    /// per row: `8 n ε₃₂ Σ_j |F_ij x_j|` (a sum of n f32 products in any
    /// order errs by at most `n ε` of the sum of magnitudes; 8 covers the
    /// lanes' partial sums and their reduction, faer's `eps * 8 * n`).
    #[test]
    fn the_classic_pass_is_the_product_within_f32_rounding() {
        let n = 1003;
        let mut rng = SplitMix64::new(3);
        let mut u = || (rng.next_u64() >> 40) as f32 / (1u64 << 24) as f32;
        let f: Vec<f32> = (0..n * n).map(|_| u() * 1e-3).collect();
        let x: [Vec<f32>; 3] = std::array::from_fn(|_| (0..n).map(|_| u()).collect());
        let mut y = [vec![0.0f32; n], vec![0.0f32; n], vec![0.0f32; n]];
        classic_pass(&f, n, &x, &mut y);
        for i in 0..n {
            let row = &f[i * n..(i + 1) * n];
            let portable = dot3(row, &x);
            // The AVX2 kernel too, which this CPU may not pick.
            #[cfg(target_arch = "x86_64")]
            let avx2 = (std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("fma"))
            .then(|| {
                // SAFETY: AVX2 and FMA checked just above.
                unsafe { dot3_avx2(row, &x) }
            });
            #[cfg(not(target_arch = "x86_64"))]
            let avx2: Option<[f32; 3]> = None;
            for c in 0..3 {
                let exact: f64 = row
                    .iter()
                    .zip(&x[c])
                    .map(|(&a, &b)| a as f64 * b as f64)
                    .sum();
                let mag: f64 = row
                    .iter()
                    .zip(&x[c])
                    .map(|(&a, &b)| (a as f64 * b as f64).abs())
                    .sum();
                let bound = 8.0 * n as f64 * f32::EPSILON as f64 * mag;
                let mut cases = vec![("classic_pass", y[c][i]), ("dot3", portable[c])];
                cases.extend(avx2.map(|a| ("dot3_avx2", a[c])));
                for (what, v) in cases {
                    assert!(
                        (v as f64 - exact).abs() <= bound,
                        "{what} row {i} channel {c}: {v} vs {exact} (bound {bound:e})"
                    );
                }
            }
        }
    }
}
