//! The transfer stage (issue 4): the OpenCL GEMM against faer, `T_k` and
//! `T_∞` on OpenCL against the f64 CPU reference, the furnace test, zero-tile
//! skipping, grey detection and the rejection of bad inputs.

mod common;

use radiosity::bake::error::BakeError;
use radiosity::bake::gemm::{self, Gemm, GemmConfig, Layout};
use radiosity::bake::transfer::{self, Bounces, InfiniteMethod, Transfer, TransferOptions};
use radiosity::core::compute::Backend;
use radiosity::synthetic;

/// f32 unit roundoff.
const U: f64 = 1.0 / (1u64 << 24) as f64;

fn run(
    f: &[f32],
    n: usize,
    albedo: &[[f32; 3]],
    bounces: Bounces,
    backend: &Backend,
) -> Result<Transfer, BakeError> {
    let options = TransferOptions {
        bounces,
        ..TransferOptions::default()
    };
    transfer::transfer(f, n, albedo, &options, backend, &mut |_, _| {})
}

/// Relative Frobenius error of every channel against the f64 reference.
fn worst_error(t: &Transfer, f: &[f32], albedo: &[[f32; 3]], bounces: Bounces) -> f64 {
    let n = t.n;
    (0..3)
        .map(|c| {
            let rho: Vec<f64> = albedo.iter().map(|a| a[c] as f64).collect();
            let r = transfer::reference(f, n, &rho, bounces).unwrap();
            gemm::relative_frobenius(t.channel(c), &r)
        })
        .fold(0.0, f64::max)
}

/// The GPU form of the kernel (16 × 16 work-items of 4 × 4 float4 outputs,
/// A transposed), run on whatever device the tests have, so that its
/// indexing is checked even where no GPU is present.
fn gpu_form() -> GemmConfig {
    GemmConfig {
        tile: 64,
        mr: 4,
        nr: 4,
        vector: 4,
        local: [16, 16],
        layout: Layout::ATransposed,
        unroll: 8,
        kb: 64,
    }
}

#[test]
fn gemm_matches_faer_within_the_blocked_summation_bound() {
    let gpu = common::gpu();
    let n = 333; // a multiple of no tile size: exercises the zero padding
    let mut rng = synthetic::Rng::new(7);
    // Signed operands, so that cancellation is exercised too.
    let a: Vec<f32> = (0..n * n)
        .map(|_| (rng.uniform() * 2.0 - 1.0) as f32)
        .collect();
    let b: Vec<f32> = (0..n * n)
        .map(|_| (rng.uniform() * 2.0 - 1.0) as f32)
        .collect();
    let d: Vec<f32> = (0..n * n).map(|_| rng.uniform() as f32).collect();
    let abs = |m: &[f32]| m.iter().map(|x| x.abs()).collect::<Vec<f32>>();
    // |D| + |A||B| in f64: the scale of the rounding error of each entry.
    let scale = gemm::reference_product(&abs(&a), &abs(&b), Some(&abs(&d)), n);
    let exact = gemm::reference_product(&a, &b, Some(&d), n);
    let exact_no_d = gemm::reference_product(&a, &b, None, n);
    let native = Gemm::new(&gpu, n).unwrap();
    // The wide GPU forms (128 × 128 tiles, K sub-blocks of 16 and 32) and
    // the same tile with K blocks of the whole tile: their products must
    // agree bit for bit (the kernel's "K sub-blocks").
    let wide: Vec<GemmConfig> = GemmConfig::gpu_wide()
        .into_iter()
        .chain([GemmConfig {
            kb: 128,
            ..GemmConfig::gpu_wide()[0]
        }])
        .collect();
    let mut wide_products: Vec<(String, Vec<f32>)> = Vec::new();
    let forms = [native, Gemm::with_config(&gpu, gpu_form()).unwrap()]
        .into_iter()
        .chain(wide.iter().map(|&c| Gemm::with_config(&gpu, c).unwrap()));
    for g in forms {
        let tile = g.config().tile;
        let padded = g.padded(n);
        // Blocked summation: each entry is a sum of at most tile products
        // in a block plus padded / tile block sums plus D, each addition
        // rounded once, so |error| ≤ γ_m (|D| + |A||B|) with
        // m = tile + padded / tile + 1 and γ_m = m u / (1 − m u) (Higham,
        // Accuracy and Stability of Numerical Algorithms, 2nd ed., 3.1 and
        // 4.2). The entries of |A||B| are about n / 4 while those of A·B are
        // about sqrt(n) / 3, so this bound is the honest one for signed data.
        let m = (tile + padded / tile + 1) as f64;
        let gamma = m * U / (1.0 - m * U);
        let (da, _) = g.upload("A", n, &a).unwrap();
        let (db, _) = g.upload("B", n, &b).unwrap();
        let (dd, _) = g.upload("D", n, &d).unwrap();
        let mut dc = g.alloc("C", n).unwrap();
        for with_d in [true, false] {
            let run = g
                .multiply(&da, &db, with_d.then_some(&dd), &mut dc, true)
                .unwrap();
            assert!(!run.nonfinite());
            let c = g.download("C", &dc).unwrap();
            let reference = if with_d { &exact } else { &exact_no_d };
            let mut worst = 0.0f64;
            for e in 0..n * n {
                let err = (c[e] as f64 - reference[e]).abs();
                worst = worst.max(err / (gamma * scale[e]));
            }
            println!(
                "{}: with D {with_d}: max error / bound = {worst:.3}, rel. Frobenius {:.2e}",
                g.config(),
                gemm::relative_frobenius(&c, reference)
            );
            assert!(worst <= 1.0, "{}: error {worst} × the bound", g.config());
            if with_d && wide.contains(g.config()) {
                wide_products.push((g.config().to_string(), c));
            }
        }
        // The tile flags of an upload match the CPU reference.
        let mut sparse = vec![0.0f32; n * n];
        sparse[5 * n + 300] = 1.0;
        sparse[200 * n + 7] = -2.0;
        let (ds, _) = g.upload("sparse", n, &sparse).unwrap();
        assert_eq!(
            g.tile_flags(&ds).unwrap(),
            gemm::tile_flags_cpu(&sparse, n, tile)
        );
    }
    assert_eq!(wide_products.len(), wide.len());
    let (first, reference) = &wide_products[0];
    for (name, c) in &wide_products[1..] {
        let differ = c
            .iter()
            .zip(reference)
            .filter(|(x, y)| x.to_bits() != y.to_bits())
            .count();
        assert_eq!(differ, 0, "{name} against {first}: {differ} entries differ");
    }
}

#[test]
fn t_k_and_t_inf_match_the_f64_reference() {
    let gpu = common::gpu();
    let backend = Backend::OpenCl(&gpu);
    let n = 333;
    let open = synthetic::open(n, 11, 0.95);
    let closed = synthetic::closed(n, 12);
    for (scene, f) in [("open", &open.f), ("closed", &closed.f)] {
        for (max_albedo, tolerance) in [(0.8, 1e-5), (0.99, 1e-3)] {
            let albedo = synthetic::colour_albedo(n, 13, max_albedo);
            for bounces in [
                Bounces::K(1),
                Bounces::K(2),
                Bounces::K(3),
                Bounces::K(8),
                Bounces::Infinite,
            ] {
                let t = run(f, n, &albedo, bounces, &backend).unwrap();
                assert!(!t.grey);
                assert_eq!(t.channels.len(), 3);
                let err = worst_error(&t, f, &albedo, bounces);
                println!(
                    "{scene} n = {n}, max albedo {max_albedo}, bounces {bounces}: rel. Frobenius error {err:.2e}, {} doublings, {} bounces summed, {} GEMMs",
                    t.stats.doublings, t.stats.terms, t.stats.gemms
                );
                assert!(
                    err < tolerance,
                    "{scene}, albedo {max_albedo}, {bounces}: error {err:.3e}"
                );
                if let Bounces::K(k) = bounces {
                    assert_eq!(t.stats.terms, k as u64);
                    assert_eq!(t.stats.gemms, 3 * transfer::planned_gemms(k));
                }
            }
        }
    }
}

#[test]
fn furnace_closed_environment_uniform_albedo() {
    // Closed environment, uniform albedo ρ, B0 = 1 everywhere: every row of
    // F sums to 1, so H = Σ_{h<k} ρ^h = (1 − ρ^k) / (1 − ρ) for T_k and
    // 1 / (1 − ρ) for T_∞, whatever F is.
    let gpu = common::gpu();
    let backend = Backend::OpenCl(&gpu);
    let n = 300;
    let closed = synthetic::closed(n, 21);
    let ones = vec![1.0f64; n];
    for (rho, tolerance) in [(0.5f64, 0.005), (0.9, 0.01), (0.99, 0.1)] {
        let albedo = vec![[rho as f32; 3]; n];
        let rho32 = rho as f32 as f64;
        for bounces in [
            Bounces::K(1),
            Bounces::K(3),
            Bounces::K(8),
            Bounces::Infinite,
        ] {
            let expected = match bounces {
                Bounces::K(k) => (1.0 - rho32.powi(k as i32)) / (1.0 - rho32),
                Bounces::Infinite => 1.0 / (1.0 - rho32),
            };
            let t = run(&closed.f, n, &albedo, bounces, &backend).unwrap();
            assert!(t.grey);
            let h = t.apply(0, &ones);
            let worst = h
                .iter()
                .map(|&h| (h / expected - 1.0).abs())
                .fold(0.0, f64::max);
            println!(
                "furnace ρ = {rho}, bounces {bounces}: H = {expected:.6} expected, max relative error {worst:.2e} ({} doublings)",
                t.stats.doublings
            );
            assert!(
                worst < tolerance,
                "ρ = {rho}, {bounces}: furnace error {worst:.3e}"
            );
            // What an exactly closed synthetic F reaches: far below the
            // tolerances above (the f32 rounding of F's rows, about 1e-7,
            // amplified by at most 1 / (1 − ρ)).
            assert!(
                worst < 2e-4,
                "ρ = {rho}, {bounces}: furnace error {worst:.3e}"
            );
        }
    }
}

#[test]
fn zero_tiles_are_skipped_exactly() {
    let gpu = common::gpu();
    let backend = Backend::OpenCl(&gpu);
    // Four closed rooms, one tile each: F, Q^m and T stay block-diagonal.
    // The device's configuration with a tile of at most 128 (the device's
    // choice depends on n; this keeps the test small).
    let config = Gemm::device_config(&gpu, 512);
    let config = GemmConfig {
        tile: config.tile.min(128),
        kb: config.kb.min(128),
        ..config
    };
    let rooms = synthetic::rooms(&[config.tile; 4], 31);
    let n = rooms.n;
    let albedo = synthetic::albedo(n, 32, 0.3, 0.9);
    for bounces in [Bounces::K(3), Bounces::Infinite] {
        let mut results = Vec::new();
        for skip in [true, false] {
            // Doubling: the series' products are the ones that skip.
            let options = TransferOptions {
                bounces,
                infinite: InfiniteMethod::Doubling,
                skip_zero_tiles: skip,
                gemm: Some(config),
            };
            let t = transfer::transfer(&rooms.f, n, &albedo, &options, &backend, &mut |_, _| {})
                .unwrap();
            println!("rooms, skip {skip}, {bounces}: {}", t.stats);
            results.push(t);
        }
        let (skipped, full) = (&results[0], &results[1]);
        assert_eq!(
            skipped.channels[0]
                .iter()
                .map(|x| x.to_bits())
                .collect::<Vec<_>>(),
            full.channels[0]
                .iter()
                .map(|x| x.to_bits())
                .collect::<Vec<_>>(),
            "skipping zero tiles changed the result"
        );
        assert_eq!(full.stats.skipped_tiles, 0);
        // Of the 4 × 4 × 4 tile products of every product only the 4 on
        // the diagonal (i = k = j) are not zero.
        assert!(
            (skipped.stats.skipped_fraction - 15.0 / 16.0).abs() < 1e-9,
            "{}",
            skipped.stats.skipped_fraction
        );
        let err = worst_error(skipped, &rooms.f, &albedo, bounces);
        assert!(err < 1e-5, "rooms: {err:.3e}");
    }
}

#[test]
fn zero_albedo_patches_end_the_chain() {
    let gpu = common::gpu();
    let backend = Backend::OpenCl(&gpu);
    let n = 333;
    let open = synthetic::open(n, 41, 0.95);
    // Two thirds of the patches are black (scattered): they are moved last,
    // where their zero columns of Q form whole zero tiles.
    let mut albedo = synthetic::albedo(n, 42, 0.2, 0.9);
    for (i, a) in albedo.iter_mut().enumerate() {
        if i % 3 != 0 {
            *a = [0.0; 3];
        }
    }
    for method in [InfiniteMethod::Doubling, InfiniteMethod::Solve] {
        let options = TransferOptions {
            infinite: method,
            ..TransferOptions::default()
        };
        let t =
            transfer::transfer(&open.f, n, &albedo, &options, &backend, &mut |_, _| {}).unwrap();
        println!("{method:?}: {}", t.stats);
        assert_eq!(t.stats.per_channel[0].zero_albedo_patches, 222);
        if method == InfiniteMethod::Doubling {
            assert!(
                t.stats.skipped_fraction > 0.3,
                "{}",
                t.stats.skipped_fraction
            );
        }
        // A zero-albedo patch is an identity row of I − diag(ρ) F: the LU
        // solve needs nothing special.
        let err = worst_error(&t, &open.f, &albedo, Bounces::Infinite);
        assert!(err < 1e-5, "{method:?}: {err:.3e}");
    }
}

/// `T_∞` by the blocked LU solve against the f64 solve, up to albedo
/// 0.999, with `n` a multiple of no block size, on the device's own
/// configuration (one tile size) and the GPU form (tile 64: 6 block steps).
/// The bound: every update adds terms of one sign (module doc of
/// `bake::solve`), so there is no cancellation for the condition number
/// `≈ 1 / (1 − ρ)` to amplify: measured 1.4–2.0e-7 at every albedo here
/// (a few f32 roundings per entry); the bound 2e-6 is 10× that. Doubling's
/// errors and the GFLOP of both are printed beside them.
#[test]
fn t_inf_by_lu_solve_matches_the_f64_solve_up_to_albedo_0_999() {
    let gpu = common::gpu();
    let backend = Backend::OpenCl(&gpu);
    let n = 333;
    let closed = synthetic::closed(n, 61);
    for config in [Gemm::device_config(&gpu, n), gpu_form()] {
        for rho in [0.5, 0.9, 0.99, 0.999] {
            // Albedos in [0.98 ρ, ρ]: the spectral radius is within 2 % of
            // ρ (the rows of a closed F sum to 1).
            let albedo = synthetic::albedo(n, 62, 0.98 * rho, rho);
            let mut errs = Vec::new();
            for method in [InfiniteMethod::Solve, InfiniteMethod::Doubling] {
                let options = TransferOptions {
                    infinite: method,
                    gemm: Some(config),
                    ..TransferOptions::default()
                };
                let t =
                    transfer::transfer(&closed.f, n, &albedo, &options, &backend, &mut |_, _| {})
                        .unwrap();
                assert_eq!(
                    t.stats.per_channel[0].method,
                    match method {
                        InfiniteMethod::Solve => "LU solve",
                        InfiniteMethod::Doubling => "doubling",
                    }
                );
                errs.push((
                    worst_error(&t, &closed.f, &albedo, Bounces::Infinite),
                    t.stats.gflop,
                ));
            }
            let bound = 2e-6;
            println!(
                "tile {}, ρ ≤ {rho}: LU error {:.2e} ({:.2} GFLOP), doubling {:.2e} ({:.2} GFLOP), bound {bound:.1e}",
                config.tile, errs[0].0, errs[0].1, errs[1].0, errs[1].1
            );
            assert!(errs[0].0 < bound, "ρ {rho}: LU error {:.3e}", errs[0].0);
        }
    }
}

#[test]
fn grey_and_shared_channels_are_computed_once() {
    let gpu = common::gpu();
    let backend = Backend::OpenCl(&gpu);
    let n = 100;
    let open = synthetic::open(n, 51, 0.9);
    let grey = synthetic::albedo(n, 52, 0.1, 0.8);
    let t = run(&open.f, n, &grey, Bounces::K(3), &backend).unwrap();
    assert!(t.grey);
    assert_eq!(t.channels.len(), 1);
    assert_eq!(t.stats.channels_computed, 1);
    assert_eq!(t.channel(2), t.channel(0));
    // R and B equal, G different: two computed, B shares R's.
    let mut rgb = synthetic::colour_albedo(n, 53, 0.8);
    for a in &mut rgb {
        a[2] = a[0];
    }
    let t = run(&open.f, n, &rgb, Bounces::K(3), &backend).unwrap();
    assert!(!t.grey);
    assert_eq!(t.channels.len(), 3);
    assert_eq!(t.stats.channels_computed, 2);
    assert_eq!(t.stats.per_channel[2].shared_with, Some(0));
    assert_eq!(t.channel(2), t.channel(0));
    assert_ne!(t.channel(1), t.channel(0));
    // Deterministic: the same input gives the same bits.
    let again = run(&open.f, n, &rgb, Bounces::K(3), &backend).unwrap();
    assert_eq!(again.channels, t.channels);
    // No patches: an empty, grey result.
    let empty = run(&[], 0, &[], Bounces::Infinite, &backend).unwrap();
    assert!(empty.grey && empty.channel(1).is_empty());
}

#[test]
fn bad_inputs_are_rejected_naming_what_is_wrong() {
    let gpu = common::gpu();
    let backend = Backend::OpenCl(&gpu);
    let n = 20;
    let open = synthetic::open(n, 61, 0.9);
    let good = synthetic::albedo(n, 62, 0.1, 0.8);
    for (bad, text) in [
        (1.0f32, "1"),
        (1.5, "1.5"),
        (-0.1, "-0.1"),
        (f32::NAN, "NaN"),
    ] {
        let mut albedo = good.clone();
        albedo[5][1] = bad;
        let err = run(&open.f, n, &albedo, Bounces::Infinite, &backend).unwrap_err();
        let msg = err.to_string();
        assert!(
            matches!(
                err,
                BakeError::Numeric {
                    stage: "transfer",
                    ..
                }
            ),
            "{msg}"
        );
        assert!(
            msg.contains("patch 5")
                && msg.contains(&format!("albedo {text}"))
                && msg.contains("channel G"),
            "{msg}"
        );
    }
    let mut f = open.f.clone();
    f[3 * n + 7] = f32::NAN;
    let err = run(&f, n, &good, Bounces::K(2), &backend).unwrap_err();
    let msg = err.to_string();
    assert!(
        msg.starts_with("transfer:") && msg.contains("F[3][7] = NaN"),
        "{msg}"
    );
    f[3 * n + 7] = f32::INFINITY;
    assert!(run(&f, n, &good, Bounces::K(2), &backend)
        .unwrap_err()
        .to_string()
        .contains("F[3][7] = inf"));
    // Row sums of 2 with albedo 0.9: the series diverges; the products'
    // epilogues catch the overflow and name the step.
    let f: Vec<f32> = open.f.iter().map(|x| x * 2.0 / 0.9).collect();
    let albedo = vec![[0.9f32; 3]; n];
    let err = run(&f, n, &albedo, Bounces::Infinite, &backend).unwrap_err();
    let msg = err.to_string();
    println!("{msg}");
    assert!(
        msg.starts_with("transfer:") && msg.contains("non-finite") && msg.contains("doubling"),
        "{msg}"
    );
    assert!(matches!(
        run(&open.f, n, &good, Bounces::K(0), &backend),
        Err(BakeError::InvalidOption {
            option: "bounces",
            ..
        })
    ));
    assert!(matches!(
        run(&open.f[1..], n, &good, Bounces::K(1), &backend),
        Err(BakeError::Mismatch { .. })
    ));
}

#[test]
fn bounce_plans_use_the_fewest_products() {
    // (doublings, Horner steps) and the products they take.
    assert_eq!(transfer::plan_bounces(1), (0, 0));
    assert_eq!(transfer::plan_bounces(3), (0, 2));
    assert_eq!(transfer::plan_bounces(8), (3, 0));
    assert_eq!(transfer::planned_gemms(8), 5);
    assert_eq!(transfer::planned_gemms(16), 7);
    assert_eq!(transfer::planned_gemms(17), 8);
    for k in 1..200 {
        assert!(transfer::planned_gemms(k) < k);
    }
    assert_eq!(transfer::expected_doublings(0.5), 5);
    assert_eq!(transfer::expected_doublings(0.99), 11);
}

#[test]
fn cpu_backend_is_the_reference() {
    let n = 50;
    let open = synthetic::open(n, 71, 0.95);
    let albedo = synthetic::colour_albedo(n, 72, 0.9);
    let t = run(&open.f, n, &albedo, Bounces::Infinite, &Backend::Cpu).unwrap();
    let rho: Vec<f64> = albedo.iter().map(|a| a[1] as f64).collect();
    let r = transfer::reference(&open.f, n, &rho, Bounces::Infinite).unwrap();
    assert!(gemm::relative_frobenius(t.channel(1), &r) < 1e-7);
    // T_∞ satisfies T = F + F diag(ρ) T (the f64 reference, checked
    // against its definition).
    let k = transfer::reference(&open.f, n, &rho, Bounces::K(400)).unwrap();
    let err = k
        .iter()
        .zip(&r)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(err < 1e-12, "{err}");
}

/// Real form factors: the Cornell box (coloured walls, so three channels)
/// and the closed cube (a furnace), from the voxelization and form-factor
/// stages.
#[test]
fn real_form_factors_cornell_box_and_closed_cube() {
    use radiosity::bake::form_factor::{self, FormFactorOptions};
    use radiosity::{bake::voxelize, core::scene};
    let gpu = common::gpu();
    let backend = Backend::OpenCl(&gpu);
    let cornell = scene::load(&common::bundled("cornell_box")).unwrap();
    let vox = voxelize::voxelize_at(&cornell, 50.0, &Backend::Cpu).unwrap();
    let ff = form_factor::form_factors(
        &cornell,
        &vox.patches,
        &vox.grid,
        &FormFactorOptions::default(),
        &backend,
        &mut |_, _| {},
    )
    .unwrap();
    let albedo: Vec<[f32; 3]> = ff
        .kept
        .iter()
        .map(|&i| vox.patches[i].albedo.map(|a| a as f32))
        .collect();
    for bounces in [Bounces::K(3), Bounces::Infinite] {
        let t = run(&ff.f, ff.n, &albedo, bounces, &backend).unwrap();
        let err = worst_error(&t, &ff.f, &albedo, bounces);
        println!(
            "Cornell box, {} patches, {bounces}: rel. Frobenius error {err:.2e}\n{}",
            ff.n, t.stats
        );
        assert!(!t.grey);
        assert!(err < 1e-5, "{err:.3e}");
    }
    let cube = scene::load(&common::bundled("closed_cube")).unwrap();
    let vox = voxelize::voxelize_at(&cube, 0.125, &Backend::Cpu).unwrap();
    let ff = form_factor::form_factors(
        &cube,
        &vox.patches,
        &vox.grid,
        &FormFactorOptions::default(),
        &backend,
        &mut |_, _| {},
    )
    .unwrap();
    let sums: Vec<f64> = (0..ff.n)
        .map(|i| {
            ff.f[i * ff.n..(i + 1) * ff.n]
                .iter()
                .map(|&x| x as f64)
                .sum()
        })
        .collect();
    let (lo, hi) = sums
        .iter()
        .fold((f64::MAX, 0.0f64), |(a, b), &s| (a.min(s), b.max(s)));
    println!(
        "closed cube: {} patches, row sums in [{lo:.6}, {hi:.6}]",
        ff.n
    );
    let ones = vec![1.0; ff.n];
    for (rho, tolerance) in [(0.5f64, 0.005), (0.9, 0.01), (0.99, 0.1)] {
        let albedo = vec![[rho as f32; 3]; ff.n];
        let t = run(&ff.f, ff.n, &albedo, Bounces::Infinite, &backend).unwrap();
        let expected = 1.0 / (1.0 - rho as f32 as f64);
        let worst = t
            .apply(0, &ones)
            .iter()
            .map(|&h| (h / expected - 1.0).abs())
            .fold(0.0, f64::max);
        println!("closed cube furnace ρ = {rho}: max relative error {worst:.2e}");
        assert!(worst < tolerance, "ρ = {rho}: {worst:.3e}");
    }
}

/// `MAX_USEFUL_BOUNCES` is where the series' tail, at most `ρ_max^k / (1 −
/// ρ_max)` of `T_∞`, falls below f32's unit roundoff; a bake asked for more
/// is refused before any work, pointing to the infinite solve.
#[test]
fn more_bounces_than_change_an_f32_result_are_refused() {
    use radiosity::bake::transfer::MAX_USEFUL_BOUNCES;
    let rho = f64::from(radiosity::core::scene::ALBEDO_MAX);
    let tail = |k: u32| rho.powi(k as i32) / (1.0 - rho);
    let u = 2f64.powi(-24);
    assert!(tail(MAX_USEFUL_BOUNCES) < u);
    assert!(tail(MAX_USEFUL_BOUNCES - 1) >= u);
    let mut c = radiosity::bake::BakeConfig::new(
        "scene.obj".into(),
        radiosity::bake::voxelize::Resolution::Patches(100),
    );
    c.transfer.bounces = Bounces::K(MAX_USEFUL_BOUNCES);
    assert!(c.validate().is_ok());
    for k in [MAX_USEFUL_BOUNCES + 1, 1_000_000_000] {
        c.transfer.bounces = Bounces::K(k);
        let e = c.validate().unwrap_err().to_string();
        assert!(e.contains("bounces") && e.contains("infinite"), "{e}");
    }
}
