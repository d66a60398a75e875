//! From radiance to pixels, the same on the CPU and in the GL shader
//! (`crates/gl/glsl/tonemap.frag`): exposure, a filmic curve, the sRGB transfer
//! function.
//!
//! - **Exposure** `k`: given, or automatic: `k = 0.18 / L̄` with `L̄` the
//!   log-average luminance `exp(mean ln(10⁻⁴ + Y))` over the pixels that
//!   see a surface (Reinhard et al., "Photographic Tone Reproduction for
//!   Digital Images", SIGGRAPH 2002), `Y = 0.2126 R + 0.7152 G + 0.0722 B`.
//! - **Curve**: the fit of the ACES filmic curve by K. Narkowicz ("ACES
//!   Filmic Tone Mapping Curve", 2015), `f(x) = x (2.51 x + 0.03) / (x (2.43
//!   x + 0.59) + 0.14)`, clamped to [0, 1], per channel on `k L`.
//! - **Output**: the sRGB OETF (IEC 61966-2-1), rounded to 8 bits.

/// Rec. 709 luminance.
pub fn luminance(c: [f32; 3]) -> f32 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// The automatic exposure of the covered pixels' radiances (module doc);
/// 1 when there are none.
pub fn auto_exposure<'a>(pixels: impl Iterator<Item = &'a [f32; 3]>) -> f32 {
    let (mut s, mut k) = (0.0f64, 0usize);
    for p in pixels {
        s += (1e-4 + luminance(*p).max(0.0) as f64).ln();
        k += 1;
    }
    if k == 0 {
        return 1.0;
    }
    (0.18 / (s / k as f64).exp()) as f32
}

/// The filmic curve (module doc).
pub fn filmic(x: f32) -> f32 {
    let x = x.max(0.0);
    ((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14)).clamp(0.0, 1.0)
}

/// The sRGB OETF of a linear value in [0, 1].
pub fn srgb_encode(v: f32) -> f32 {
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// A pixel's 8-bit sRGB colour from its radiance and the exposure.
pub fn to_srgb8(l: [f32; 3], exposure: f32) -> [u8; 3] {
    l.map(|c| (srgb_encode(filmic(exposure * c)) * 255.0 + 0.5).clamp(0.0, 255.0) as u8)
}

/// Writes a linear RGB image as PFM (portable float map: little-endian,
/// bottom row first), `rows` top row first.
pub fn write_pfm(
    path: &std::path::Path,
    width: usize,
    height: usize,
    rows: &[[f32; 3]],
) -> std::io::Result<()> {
    let mut out = format!("PF\n{width} {height}\n-1.0\n").into_bytes();
    for y in (0..height).rev() {
        for p in &rows[y * width..(y + 1) * width] {
            for c in p {
                out.extend_from_slice(&c.to_le_bytes());
            }
        }
    }
    radiosity_bakefile::container::write_atomic(path, &out, None)
}
