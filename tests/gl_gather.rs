//! The GL gather (`glsl/gather.comp`, `src/gl/gather.rs`) against its CPU
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
fn gl_gather_matches_the_cpu_gather_within_the_decoders_rounding() {
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
    // The bound (module doc of gl::gather): each dense entry within `k`
    // steps of a byte of the log scale of the CPU's, a factor e^{k L/255};
    // the sparse part exact, all terms non-negative; plus the shader's f32
    // `exp` (GLSL 4.50 section 4.7.1 allows 3 ULP of exp2 of a scaled
    // argument: taken as 1e-4 relative) and f32 summation of a few hundred
    // terms in either order (1e-5 relative). k = 1 for BC1 (llvmpipe
    // truncates the interpolated palette entries to bytes, TOOLCHAIN.md);
    // k = 2 for BC4, whose 8-level interpolation llvmpipe decodes through
    // bytes too (measured up to 1.2 steps below bcdec's float decode);
    // k = 0 for BC6H (decoded bit-exactly, TOOLCHAIN.md), f16 and f32 (the
    // stored values themselves).
    let k = match format {
        DenseFormat::Bc4 => 2.0,
        DenseFormat::Bc1 => 1.0,
        _ => 0.0,
    };
    let step = (k * e.log_range as f64 / 255.0).exp() - 1.0;
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
        let active = ActiveColumns::of(b, e.index.tile, false);
        let mut h_cpu: [Vec<f32>; 3] = std::array::from_fn(|_| vec![0.0; n]);
        cpu.gather(b, &active, &mut h_cpu);
        let h_gl = g.gather(&gl.gl, b, &active).unwrap();
        let mut worst = 0.0f64;
        for c in 0..3 {
            for i in 0..n {
                let (x, y) = (h_gl[c][i] as f64, h_cpu[c][i] as f64);
                let bound = (step + 1e-4 + 1e-5) * y + 1e-30;
                worst = worst.max((x - y).abs() / bound);
                assert!(
                    (x - y).abs() <= bound,
                    "case {case}, channel {c}, row {i}: GL {x} against CPU {y} (bound {bound:e})"
                );
            }
        }
        // Skipping zero columns changes nothing (a skipped term is v · 0).
        let all = ActiveColumns::of(b, e.index.tile, true);
        let h_all = g.gather(&gl.gl, b, &all).unwrap();
        assert_eq!(h_all, h_gl, "case {case}: skipping changed H");
        println!(
            "{kind} (column scales {scaled}), case {case}: {} of {} tile columns active; worst |GL - CPU| / bound = {worst:.2e} ({k} byte step(s) = {:.2} %)",
            active.mask.iter().filter(|&&m| m != 0).count(),
            active.mask.len(),
            100.0 * step
        );
    }
    g.delete(&gl.gl);
}
