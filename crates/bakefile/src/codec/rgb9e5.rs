//! OpenGL's shared-exponent format `GL_RGB9_E5`, as specified by
//! EXT_texture_shared_exponent (section "Encoding of shared exponent
//! formats"): N = 9 mantissa bits, exponent bias B = 15, E_max = 31; bits
//! 0–8 red, 9–17 green, 18–26 blue, 27–31 the exponent.

const N: i32 = 9;
const B: i32 = 15;
const E_MAX: i32 = 31;

/// The largest representable value, (2^N − 1) / 2^N · 2^(E_max − B).
pub const MAX: f32 = 65408.0;

/// Packs three values (negative and NaN are taken as 0, values above
/// [`MAX`] as [`MAX`]) with the specification's rounding.
pub fn pack(v: [f32; 3]) -> u32 {
    let c = v.map(|x| if x > 0.0 { x.min(MAX) as f64 } else { 0.0 });
    let max_c = c[0].max(c[1]).max(c[2]);
    // exp_shared' = max(−B − 1, floor(log2(max_c))) + 1 + B; a zero
    // triple takes the smallest exponent.
    let floor_log2 = if max_c > 0.0 {
        max_c.log2().floor() as i32
    } else {
        -B - 1
    };
    let mut e = floor_log2.max(-B - 1) + 1 + B;
    let step = |e: i32| 2f64.powi(e - B - N);
    let max_s = (max_c / step(e) + 0.5).floor() as i32;
    if max_s == 1 << N {
        e += 1;
    }
    debug_assert!((0..=E_MAX).contains(&e));
    let m = c.map(|x| ((x / step(e) + 0.5).floor() as u32).min((1 << N) - 1));
    m[0] | m[1] << 9 | m[2] << 18 | (e as u32) << 27
}

/// The three values of a packed word: `mantissa · 2^(e − B − N)`.
pub fn unpack(p: u32) -> [f32; 3] {
    let e = (p >> 27) as i32;
    let step = 2f64.powi(e - B - N);
    [0, 9, 18].map(|s| (((p >> s) & 0x1ff) as f64 * step) as f32)
}
