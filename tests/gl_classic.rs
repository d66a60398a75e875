//! Classic radiosity on the GPU (`crates/gl/glsl/classic.comp`, `crates/gl/src/classic.rs`)
//! against its CPU reference (`bench::frame::classic`) and the exact f64
//! series, and the copy kernel (`crates/gl/glsl/copy.comp`, the memory roof of
//! `bench frame`) against the identity, on a headless EGL context (Mesa
//! llvmpipe here; the test fails, naming what to install, where there is
//! none).

use radiosity::bench::frame::{classic, exact_series};
use radiosity::core::math::SplitMix64;
use radiosity::gl::classic::GlClassic;
use radiosity::gl::context::Headless;
use radiosity::gl::copy::GlCopy;

fn context() -> Headless {
    Headless::new().unwrap_or_else(|e| {
        panic!("no headless OpenGL 4.5 (EGL on Mesa llvmpipe: run scripts/setup): {e}")
    })
}

#[test]
fn gl_classic_bounces_match_the_exact_series_within_f32_rounding() {
    let gl = context();
    println!("GL: {} ({})", gl.renderer(), gl.device);
    // n not a multiple of 4 (padded rows) and larger than one chunk of
    // staged columns (1024); rows summing to at most 0.9, albedos below 1.
    let n = 1027;
    let mut rng = SplitMix64::new(11);
    let mut u = || (rng.next_u64() >> 40) as f32 / (1u64 << 24) as f32;
    let f: Vec<f32> = (0..n * n).map(|_| u() * 1.8 / n as f32).collect();
    let albedo: Vec<[f32; 3]> = (0..n).map(|_| [0.9 * u(), 0.9 * u(), 0.9 * u()]).collect();
    // A few lit patches, the rest dark (as a light's B0).
    let b0: [Vec<f32>; 3] =
        std::array::from_fn(|_| (0..n).map(|j| if j % 7 == 3 { u() } else { 0.0 }).collect());
    let g = GlClassic::new(&gl.gl, &f, n, &albedo).unwrap();
    // Every term is ≥ 0, so each computed pass is within a relative
    // γ_(n+1) of F times its (computed) input (Higham, Accuracy and
    // Stability of Numerical Algorithms, eq. 3.5: n products and sums),
    // and x = ρ ∘ y adds one rounding u: after h passes a term is within
    // (1 + γ + u)^h − 1 ≈ h (γ + u) of its exact value, and H's k additions
    // add k u. So |H − H_exact| ≤ (k (γ + u) + k u) H_exact to first order
    // (1 % margin for the second), for the GPU and for the CPU alike.
    let unit = f64::from(f32::EPSILON) / 2.0;
    let m = (n + 1) as f64;
    let gamma = m * unit / (1.0 - m * unit);
    for k in [1, 2, 3, 9] {
        let exact = exact_series(&f, n, &albedo, &b0, Some(k));
        let cpu = classic(&f, n, &albedo, &b0, k);
        let gpu = g.bounces(&gl.gl, &b0, k).unwrap();
        let rel = 1.01 * k as f64 * (gamma + 2.0 * unit);
        let mut worst = 0.0f64;
        for c in 0..3 {
            for i in 0..n {
                let bound = rel * exact[c][i] + f64::from(f32::MIN_POSITIVE);
                for (what, v) in [("GL", gpu[c][i]), ("CPU", cpu[c][i])] {
                    let d = (f64::from(v) - exact[c][i]).abs();
                    worst = worst.max(d / bound);
                    assert!(
                        d <= bound,
                        "{k} bounces, channel {c}, patch {i}: {what} {v} against exact {} (bound {bound:e})",
                        exact[c][i]
                    );
                }
            }
        }
        // The same passes again: the same bits (fixed summation order).
        assert_eq!(
            g.bounces(&gl.gl, &b0, k).unwrap(),
            gpu,
            "{k} bounces: not deterministic"
        );
        println!("{k} bounces: worst |H − exact| / bound = {worst:.2e} (bound {rel:.2e} relative)");
    }
    g.delete(&gl.gl);
}

#[test]
fn gl_copy_copies_every_word() {
    let gl = context();
    // Not a multiple of 16 bytes (rounded up) and more words than one
    // dispatch has invocations (each strides over the buffer).
    let c = GlCopy::new(&gl.gl, (1 << 24) + 5).unwrap();
    c.run(&gl.gl);
    let words = c.read(&gl.gl);
    assert_eq!(words.len() as u64 * 4, c.bytes_moved() / 2);
    for (k, &w) in words.iter().enumerate() {
        assert_eq!(w, k as u32, "word {k}");
    }
    let bw = c.bandwidth(&gl.gl, 3).unwrap();
    assert!(bw.is_finite() && bw > 0.0, "bandwidth {bw}");
    println!("copy: {:.2} GB/s on {}", bw / 1e9, gl.renderer());
    c.delete(&gl.gl);
}
