//! `radiosity bench transfer`: the GEMM against faer, and the stress table
//! of `T_∞` against the f64 reference over albedos and sizes.

use crate::bake::error::BakeError;
use crate::bake::gemm::{reference_product, relative_frobenius, to_faer, Gemm};
use crate::bake::transfer::{reference, transfer, Bounces, InfiniteMethod, TransferOptions};
use crate::core::compute::Backend;
use crate::synthetic;
use serde::Serialize;
use std::fmt::Write as _;
use std::time::Instant;

/// One stress case: `n` patches in `rooms` closed rooms of equal size that
/// do not see each other (1: one closed environment).
#[derive(Clone, Copy, Debug, Serialize)]
pub struct StressCase {
    pub n: usize,
    pub rooms: usize,
}

/// The stress benchmark: for each case and each albedo `a`, a closed
/// synthetic environment ([`synthetic::rooms`]) with uniform grey albedo
/// `a` (the worst case for convergence: the spectral radius is `a`), `T_∞`
/// on `backend` against the f64 LU reference (per room; entries between
/// rooms must be exactly zero) and against the furnace identity
/// `T_∞ · 1 = 1 / (1 − a)`, with the count of non-finite entries. Then the
/// cost of `T_3` and `T_8` beside `T_∞` on the first case. Returns markdown.
pub fn bench_stress(
    cases: &[StressCase],
    albedos: &[f64],
    backend: &Backend,
) -> Result<String, BakeError> {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "| n | rooms | albedo | T_∞ by | spectral bound | doublings | bounces summed | GEMMs | tiles skipped | GEMM device s | GFLOP/s | stage wall s | rel. Frobenius vs f64 | max rel. entry error | furnace max error | non-finite | f64 reference s |"
    );
    let _ = writeln!(
        out,
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
    );
    for case in cases {
        let rooms = case.rooms.max(1);
        let m = case.n / rooms;
        let scene = synthetic::rooms(&vec![m; rooms], 0x57e55 + case.n as u64);
        let n = scene.n;
        for (&a, method) in albedos
            .iter()
            .flat_map(|a| [(a, InfiniteMethod::Solve), (a, InfiniteMethod::Doubling)])
        {
            let albedo = vec![[a as f32; 3]; n];
            let options = TransferOptions {
                infinite: method,
                ..TransferOptions::default()
            };
            let t = transfer(&scene.f, n, &albedo, &options, backend, &mut |_, _| {})?;
            let tm = t.channel(0);
            let nonfinite = tm.iter().filter(|x| !x.is_finite()).count();
            // Furnace: H_i = Σ_j T_ij = 1 / (1 − a) (a as stored in f32).
            let a32 = a as f32 as f64;
            let furnace = (0..n)
                .map(|i| {
                    let h: f64 = tm[i * n..(i + 1) * n].iter().map(|&x| x as f64).sum();
                    (h * (1.0 - a32) - 1.0).abs()
                })
                .fold(0.0, f64::max);
            // The f64 reference, room by room.
            let ref_start = Instant::now();
            let (mut num, mut den, mut worst) = (0.0f64, 0.0f64, 0.0f64);
            let mut outside_nonzero = 0usize;
            for r in 0..rooms {
                let o = r * m;
                let block: Vec<f32> = (0..m * m)
                    .map(|e| scene.f[(o + e / m) * n + o + e % m])
                    .collect();
                let reference_block = reference(&block, m, &vec![a32; m], Bounces::Infinite)?;
                for i in 0..m {
                    for j in 0..m {
                        let x = tm[(o + i) * n + o + j] as f64;
                        let y = reference_block[i * m + j];
                        num += (x - y).powi(2);
                        den += y * y;
                        if y > 0.0 {
                            worst = worst.max((x - y).abs() / y);
                        }
                    }
                }
            }
            if rooms > 1 {
                for i in 0..n {
                    for j in 0..n {
                        if i / m != j / m && tm[i * n + j] != 0.0 {
                            outside_nonzero += 1;
                        }
                    }
                }
            }
            let ref_seconds = ref_start.elapsed().as_secs_f64();
            let s = &t.stats;
            let _ = writeln!(
                out,
                "| {n} | {rooms} | {a} | {} | {:.4} | {} | {} | {} | {:.1} % | {:.2} | {:.1} | {:.2} | {:.1e} | {:.1e} | {:.1e} | {}{} | {:.1} |",
                s.per_channel[0].method,
                s.spectral_bound,
                s.doublings,
                s.terms,
                s.gemms,
                100.0 * s.skipped_fraction,
                s.seconds_gemm,
                s.gflops,
                s.seconds_total,
                (num / den).sqrt(),
                worst,
                furnace,
                nonfinite,
                if rooms > 1 { format!(" ({outside_nonzero} non-zero between rooms)") } else { String::new() },
                ref_seconds
            );
        }
    }
    if let (Some(case), Some(&a)) = (
        cases.first(),
        albedos.iter().find(|&&a| a >= 0.9).or(albedos.first()),
    ) {
        let scene = synthetic::rooms(
            &vec![case.n / case.rooms.max(1); case.rooms.max(1)],
            0x57e55 + case.n as u64,
        );
        let n = scene.n;
        let albedo = vec![[a as f32; 3]; n];
        let a32 = a as f32 as f64;
        let _ = writeln!(
            out,
            "\nCost of the bounce count, n = {n}, {} room(s), uniform albedo {a}: H = T · 1 against the converged 1 / (1 − a) = {:.3}.\n",
            case.rooms.max(1),
            1.0 / (1.0 - a32)
        );
        let _ = writeln!(
            out,
            "| bounces (method) | GEMM launches | GEMM device s | stage wall s | light captured H / H_∞ |"
        );
        let _ = writeln!(out, "|---|---|---|---|---|");
        for (bounces, infinite) in [
            (Bounces::K(1), InfiniteMethod::Solve),
            (Bounces::K(3), InfiniteMethod::Solve),
            (Bounces::K(8), InfiniteMethod::Solve),
            (Bounces::Infinite, InfiniteMethod::Doubling),
            (Bounces::Infinite, InfiniteMethod::Solve),
        ] {
            let options = TransferOptions {
                bounces,
                infinite,
                ..TransferOptions::default()
            };
            let t = transfer(&scene.f, n, &albedo, &options, backend, &mut |_, _| {})?;
            let tm = t.channel(0);
            let h: f64 = tm[..n].iter().map(|&x| x as f64).sum();
            let _ = writeln!(
                out,
                "| {bounces} ({}) | {} | {:.2} | {:.2} | {:.3} |",
                t.stats.per_channel[0].method,
                t.stats.gemms,
                t.stats.seconds_gemm,
                t.stats.seconds_total,
                h * (1.0 - a32)
            );
        }
    }
    Ok(out)
}

/// GEMM throughput on `backend` against faer's f32 product (all threads of
/// the global rayon pool) on the same random dense matrices, in the same
/// run, interleaved so that both see the same machine load: best of
/// `repeat` for each. OpenCL time is the kernel's device time (profiling
/// events) on the padded matrices, and its GFLOP/s count `2n³` of the
/// unpadded size, so padding counts against it. The error column is the
/// relative Frobenius error of the OpenCL product against faer in f64.
/// Returns a markdown table.
pub fn bench_gemm(sizes: &[usize], repeat: usize, backend: &Backend) -> Result<String, BakeError> {
    let repeat = repeat.max(1);
    let mut out = String::new();
    let gpu = match backend {
        Backend::OpenCl(gpu) => Some(*gpu),
        Backend::Cpu => None,
    };
    let _ = writeln!(
        out,
        "GEMM C = A·B, f32, square n × n, dense random operands in [0, 1). OpenCL device: {}. faer 0.24 f32 on {} rayon threads. GFLOP/s = 2n³ / best time of {repeat}.\n",
        gpu.map_or("none (CPU backend)".to_string(), |g| format!(
            "{} ({}, {} compute units)",
            g.info().name,
            g.info().platform,
            g.info().compute_units
        )),
        rayon::current_num_threads()
    );
    // The device's own FMA peak, measured in this run (`bake::peak`).
    let peak = match gpu {
        Some(g) => {
            let iterations = if g.info().kind == "GPU" {
                16_384
            } else {
                1 << 20
            };
            let p = crate::bake::peak::measure(g, iterations, 5)?;
            let _ = writeln!(
                out,
                "Measured f32 FMA peak of the device: {:.1} GFLOP/s ({} work-items × {} chains of float{} × {} FMAs, best of 5).\n",
                p.gflops,
                p.work_items,
                crate::bake::peak::CHAINS,
                p.vector_width,
                p.iterations
            );
            Some(p.gflops)
        }
        None => None,
    };
    let _ = writeln!(
        out,
        "| n | OpenCL configuration | padded | OpenCL GFLOP/s | of the measured peak | faer f32 GFLOP/s | OpenCL / faer | OpenCL rel. error vs f64 |"
    );
    let _ = writeln!(out, "|---|---|---|---|---|---|---|---|");
    for &n in sizes {
        let mut rng = crate::core::math::SplitMix64::new(0x5eed_0000 + n as u64);
        let a: Vec<f32> = (0..n * n).map(|_| rng.uniform() as f32).collect();
        let b: Vec<f32> = (0..n * n).map(|_| rng.uniform() as f32).collect();
        let flop = 2.0 * (n as f64).powi(3);
        let (fa, fb) = (to_faer(&a, n, |x| x), to_faer(&b, n, |x| x));
        let mut fc = faer::Mat::<f32>::zeros(n, n);
        let mut t_faer = f64::INFINITY;
        let mut t_cl = f64::INFINITY;
        let mut device = match gpu {
            Some(gpu) => {
                let g = Gemm::new(gpu, n)?;
                let (da, _) = g.upload("A", n, &a)?;
                let (db, _) = g.upload("B", n, &b)?;
                let dc = g.alloc("C", n)?;
                Some((g, da, db, dc))
            }
            None => None,
        };
        for _ in 0..repeat {
            let t = Instant::now();
            faer::linalg::matmul::matmul(
                fc.as_mut(),
                faer::Accum::Replace,
                fa.as_ref(),
                fb.as_ref(),
                1.0f32,
                faer::Par::rayon(0),
            );
            t_faer = t_faer.min(t.elapsed().as_secs_f64());
            if let Some((g, da, db, dc)) = device.as_mut() {
                t_cl = t_cl.min(g.multiply(da, db, None, dc, true)?.seconds);
            }
        }
        match device {
            Some((g, _, _, dc)) => {
                let c = g.download("C", &dc)?;
                let err = relative_frobenius(&c, &reference_product(&a, &b, None, n));
                let gflops = flop / t_cl * 1e-9;
                let _ = writeln!(
                    out,
                    "| {n} | {} | {} | {gflops:.1} | {:.1} % | {:.1} | {:.2} | {err:.1e} |",
                    g.config(),
                    g.padded(n),
                    100.0 * gflops / peak.unwrap_or(f64::NAN),
                    flop / t_faer * 1e-9,
                    t_faer / t_cl
                );
            }
            None => {
                let _ = writeln!(out, "| {n} | | | | | {:.1} | | |", flop / t_faer * 1e-9);
            }
        }
    }
    Ok(out)
}

/// `T_∞` of a real scene by the LU solve and by doubling in the same run,
/// against faer's f64 solve: for each patch target, the bake's first stages
/// (load, voxelize, form factors), then the three computations of one
/// channel (R: the channel of the largest albedos, so doubling's worst) on
/// the same `F`. Returns markdown with times, products and errors.
pub fn bench_solve(
    scene: &std::path::Path,
    patches: &[usize],
    backend: &Backend,
    progress: &mut dyn FnMut(&str),
) -> anyhow::Result<String> {
    use crate::bake::voxelize::Resolution;
    use crate::bake::{self, BakeConfig};
    let mut out = String::new();
    let _ = writeln!(
        out,
        "| patch target | n | T_∞ by | GEMM launches | GFLOP | GEMM device s | GFLOP/s | stage wall s | rel. Frobenius vs f64 | max rel. entry error (entries ≥ 1e-6 of the max) |"
    );
    let _ = writeln!(out, "|---|---|---|---|---|---|---|---|---|---|");
    for &p in patches {
        let mut config = BakeConfig::new(scene.to_path_buf(), Resolution::Patches(p));
        config.transfer.bounces = Bounces::K(1);
        let st = bake::transfer_stages(&config, backend, progress)?;
        let n = st.form_factors.n;
        let f = &st.form_factors.f;
        let rho: Vec<[f32; 3]> = st.albedo.iter().map(|a| [a[0]; 3]).collect();
        progress(&format!("f64 reference solve, n = {n}"));
        let start = Instant::now();
        let rho64: Vec<f64> = rho.iter().map(|a| a[0] as f64).collect();
        let reference_t = reference(f, n, &rho64, Bounces::Infinite)?;
        let ref_seconds = start.elapsed().as_secs_f64();
        let max = reference_t.iter().cloned().fold(0.0f64, f64::max);
        for method in [InfiniteMethod::Solve, InfiniteMethod::Doubling] {
            progress(&format!("T_inf by {method:?}, n = {n}"));
            let options = TransferOptions {
                infinite: method,
                ..TransferOptions::default()
            };
            let t = transfer(f, n, &rho, &options, backend, &mut |_, _| {})?;
            let tm = t.channel(0);
            let worst = tm
                .iter()
                .zip(&reference_t)
                .filter(|(_, &y)| y >= 1e-6 * max)
                .map(|(&x, &y)| (x as f64 - y).abs() / y)
                .fold(0.0, f64::max);
            let s = &t.stats;
            let _ = writeln!(
                out,
                "| {p} | {n} | {} | {} | {:.0} | {:.1} | {:.1} | {:.1} | {:.1e} | {:.1e} |",
                s.per_channel[0].method,
                s.gemms,
                s.gflop,
                s.seconds_gemm,
                s.gflops,
                s.seconds_total,
                relative_frobenius(tm, &reference_t),
                worst
            );
        }
        let _ = writeln!(
            out,
            "| {p} | {n} | f64 reference (faer LU, partial pivoting) | — | — | — | — | {ref_seconds:.1} | 0 | 0 |"
        );
    }
    Ok(out)
}
