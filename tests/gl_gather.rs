//! The GL gather (`crates/gl/glsl/gather.comp`, `crates/gl/src/gather.rs`) against its CPU
//! reference (`runtime::gather`), on a headless EGL context (Mesa llvmpipe
//! here; the test fails, naming what to install, where there is none).

use radiosity::bake::encode;
use radiosity::bake::transfer::{reference, Bounces};
use radiosity::bakefile::codec::{CodecKind, DenseFormat, SparseValues, LOG_RANGE_AUTO};
use radiosity::gl::context::Headless;
use radiosity::gl::gather::GlGather;
use radiosity::runtime::gather::{ActiveColumns, CompressedGather};
use radiosity::synthetic;

fn context() -> Headless {
    Headless::new().unwrap_or_else(|e| {
        panic!("no headless OpenGL 4.5 (EGL on Mesa llvmpipe: run scripts/setup): {e}")
    })
}

#[test]
fn gl_gather_matches_the_cpu_gather_up_to_f32_summation_order() {
    let gl = context();
    println!("GL: {} ({})", gl.renderer(), gl.device);
    // Three closed rooms that do not see each other (zero tiles), n a
    // multiple of neither the tile nor the BC1 block, colour albedos.
    let rooms = synthetic::rooms(&[150, 91, 70], 5);
    let n = rooms.n;
    let colour = synthetic::colour_albedo(n, 6, 0.8);
    let grey = synthetic::albedo(n, 6, 0.2, 0.8);
    let bc4 = CodecKind::Bc4Log {
        top_fraction: 0.02,
        log_range: LOG_RANGE_AUTO,
        sparse: SparseValues::Rgb9e5,
    };
    // Every format the file can hold: BC1 (colour), BC4 of one channel (a
    // grey scene) and of three, BC6H, f16 and f32 (colour and grey).
    for (albedo, kind, format, channels) in [
        (&colour, CodecKind::default(), DenseFormat::Bc1, 3),
        (&grey, CodecKind::default(), DenseFormat::Bc4, 1),
        (&colour, bc4, DenseFormat::Bc4, 3),
        (&colour, CodecKind::Bc6h, DenseFormat::Bc6h, 3),
        (&colour, CodecKind::F16, DenseFormat::F16, 3),
        (&grey, CodecKind::F16, DenseFormat::F16, 1),
        (&colour, CodecKind::F32, DenseFormat::F32, 3),
        (&grey, CodecKind::F32, DenseFormat::F32, 1),
    ] {
        check(&gl, &rooms.f, n, albedo, kind, format, channels, false);
    }
    // Column scales (the bake's `s`, here over four decades): the stored
    // matrix is T' = T diag(1/s) and both gathers multiply s ∘ B0.
    for (albedo, kind, format, channels) in [
        (&colour, CodecKind::default(), DenseFormat::Bc1, 3),
        (&grey, CodecKind::default(), DenseFormat::Bc4, 1),
        (&colour, CodecKind::F32, DenseFormat::F32, 3),
    ] {
        check(&gl, &rooms.f, n, albedo, kind, format, channels, true);
    }
}

/// One matrix: GL against CPU over three lightings (module doc), with
/// column scales when `scaled`.
#[allow(clippy::too_many_arguments)]
fn check(
    gl: &Headless,
    f: &[f32],
    n: usize,
    albedo: &[[f32; 3]],
    kind: CodecKind,
    format: DenseFormat,
    channels: usize,
    scaled: bool,
) {
    let t: Vec<Vec<f32>> = (0..3)
        .map(|c| {
            let rho: Vec<f64> = albedo.iter().map(|a| a[c] as f64).collect();
            reference(f, n, &rho, Bounces::Infinite)
                .unwrap()
                .iter()
                .map(|&x| x as f32)
                .collect()
        })
        .collect();
    let s: Vec<f32> = (0..n)
        .map(|j| {
            if scaled {
                10f32.powf(-4.0 * ((j * 29) % n) as f32 / n as f32)
            } else {
                1.0
            }
        })
        .collect();
    let t: Vec<Vec<f32>> = t
        .iter()
        .map(|t| t.iter().enumerate().map(|(k, v)| v / s[k % n]).collect())
        .collect();
    let mut e = encode::encode(kind, [&t[0], &t[1], &t[2]], n).unwrap();
    if scaled {
        e.col_scale = s;
    }
    assert_eq!((e.format, e.channels), (format, channels));
    assert!(
        e.index.cols.len() < e.index.tiles_per_side.pow(2),
        "zero tiles exist"
    );
    let cpu = CompressedGather::new(&e, false);
    let g = GlGather::new(&gl.gl, &e).unwrap();
    // The bound: GL and CPU decode the same f32 entries (the shader
    // computes BC1's palette bytes, BC4's levels, BC6H's halves and the
    // sparse values with the CPU's arithmetic and tables) and multiply
    // them by the same f32 `s ∘ B0`; they differ only in the order of their
    // f32 sums. Each is within `γ_m Σ_j |T̃_ij x_j|` of the exact sum of its
    // m ≤ n + 1 terms (γ_m = m u / (1 − m u), u = 2⁻²⁴: Higham, Accuracy and
    // Stability of Numerical Algorithms, eq. 3.5, plus one rounding of each
    // product), so the two are within twice that. A decoder one byte step
    // of the log scale off (what texture units gave) errs by e^{L/255} − 1,
    // 1.5 % at L = 4: hundreds of times this bound.
    let decoded = e.decode();
    let u = f64::from(f32::EPSILON) / 2.0;
    let m = (n + 1) as f64;
    let gamma = m * u / (1.0 - m * u);
    let mut rng = synthetic::Rng::new(9);
    for case in 0..3 {
        // Case 0: every patch lit; 1: the second room dark (its columns
        // are zero: tile columns skipped); 2: one patch lit.
        let b0: [Vec<f32>; 3] = std::array::from_fn(|_| {
            (0..n)
                .map(|j| {
                    let lit = match case {
                        0 => true,
                        1 => !(150..241).contains(&j),
                        _ => j == 17,
                    };
                    if lit {
                        rng.uniform() as f32
                    } else {
                        0.0
                    }
                })
                .collect()
        });
        let b: [&[f32]; 3] = [&b0[0], &b0[1], &b0[2]];
        // Σ_j |T̃_ij x_j| per channel and row, x = s ∘ B0 as both round it.
        let x = radiosity::bakefile::codec::scaled_input(b, &e.col_scale);
        let x: [&[f32]; 3] = if e.col_scale.is_empty() {
            b
        } else {
            [&x[0], &x[1], &x[2]]
        };
        let magnitude = |c: usize, i: usize| -> f64 {
            (0..n)
                .map(|j| {
                    (decoded[c][i * n + j] as f64 / e.col_scale.get(j).map_or(1.0, |&s| s as f64)
                        * x[c][j] as f64)
                        .abs()
                })
                .sum()
        };
        let active = ActiveColumns::of(b, e.index.tile, false);
        let mut h_cpu: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0; n]);
        cpu.gather(b, &active, &mut h_cpu);
        let h_gl = g.gather(&gl.gl, b, &active).unwrap();
        // Skipping inactive tile columns changes only the order of the sums.
        let all = ActiveColumns::of(b, e.index.tile, true);
        let h_all = g.gather(&gl.gl, b, &all).unwrap();
        // The same frame twice: the same bits (fixed summation order).
        assert_eq!(
            g.gather(&gl.gl, b, &active).unwrap(),
            h_gl,
            "case {case}: GL gather not deterministic"
        );
        let mut worst = 0.0f64;
        for c in 0..3 {
            for i in 0..n {
                let bound = 2.0 * gamma * magnitude(c, i) + f64::from(f32::MIN_POSITIVE);
                let y = h_cpu[c][i] as f64;
                for (what, v) in [("GL", h_gl[c][i]), ("GL over every column", h_all[c][i])] {
                    let d = (v as f64 - y).abs();
                    worst = worst.max(d / bound);
                    assert!(
                        d <= bound,
                        "case {case}, channel {c}, row {i}: {what} {v} against CPU {y} (bound {bound:e})"
                    );
                }
            }
        }
        println!(
            "{kind} (column scales {scaled}), case {case}: {} of {} tile columns active; worst |GL - CPU| / bound = {worst:.2e} (bound 2 γ_{m} Σ|T̃ x|, γ = {gamma:.2e})",
            active.mask.iter().filter(|&&m| m != 0).count(),
            active.mask.len(),
        );
    }
    g.delete(&gl.gl);
}
