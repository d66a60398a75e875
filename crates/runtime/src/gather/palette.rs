//! The decoding tables of the block codecs, shared by every gather path:
//! BC1's palettes per endpoint pair and mode (the values `bcdec_rs` decodes
//! to, through the channel's log scale), the key arithmetic that finds a
//! block's entries in them, and BC4's eight levels.

/// The BC1 palette tables of one channel ([`super`]'s module doc).
pub(super) struct Bc1Table {
    /// `[mode][e0 << bits | e1]` → 4 decoded values (5-bit red and blue,
    /// 6-bit green endpoints; [`bc1_keys`] computes the index).
    pub(super) values: Vec<[f32; 4]>,
}

fn expand5(v: u32) -> u32 {
    (v * 527 + 23) >> 6
}

fn expand6(v: u32) -> u32 {
    (v * 259 + 33) >> 6
}

/// `bcdec_rs`'s BC1 palette of one channel: endpoints `a`, `b` (5 or 6
/// bits), 4-colour mode or not.
pub(super) fn bc1_palette_bytes(a: u32, b: u32, six: bool, four: bool) -> [u8; 4] {
    let (e0, e1) = if six {
        (expand6(a), expand6(b))
    } else {
        (expand5(a), expand5(b))
    };
    if four {
        let (c2, c3) = if six {
            (
                ((2 * a + b) * 2763 + 1039) >> 11,
                ((a + 2 * b) * 2763 + 1039) >> 11,
            )
        } else {
            (((2 * a + b) * 351 + 61) >> 7, ((a + 2 * b) * 351 + 61) >> 7)
        };
        [e0 as u8, e1 as u8, c2 as u8, c3 as u8]
    } else {
        let c2 = if six {
            ((a + b) * 4145 + 1019) >> 11
        } else {
            ((a + b) * 1053 + 125) >> 8
        };
        [e0 as u8, e1 as u8, c2 as u8, 0]
    }
}

/// The 8 decoded levels of a BC4 block with endpoints `r0`, `r1` (8-level
/// interpolation when `r0 > r1`, else 6 levels, 0 and the top), from the
/// channel's tables by the interpolation's numerator.
#[inline(always)]
pub(super) fn bc4_palette(t7: &[f32; 1786], t5: &[f32; 1276], r0: u8, r1: u8) -> [f32; 8] {
    let (r0, r1) = (r0 as usize, r1 as usize);
    let mut pal = [0.0f32; 8];
    if r0 > r1 {
        pal[0] = t7[7 * r0];
        pal[1] = t7[7 * r1];
        for (i, p) in pal.iter_mut().enumerate().skip(2) {
            *p = t7[(8 - i) * r0 + (i - 1) * r1];
        }
    } else {
        pal[0] = t5[5 * r0];
        pal[1] = t5[5 * r1];
        for (i, p) in pal.iter_mut().enumerate().take(6).skip(2) {
            *p = t5[(6 - i) * r0 + (i - 1) * r1];
        }
        pal[6] = 0.0;
        pal[7] = t5[5 * 255];
    }
    pal
}

/// The palette-table keys of one BC1 block (`word`: its 8 bytes, little
/// endian): the entries of its red, green and blue palettes in the
/// [`Bc1Table`]s (`[mode][e0 << bits | e1]`), and its 32 index bits. The
/// one key arithmetic of every BC1 path (the AVX2 path's vector copy of it
/// is tested against the portable path).
pub(super) fn bc1_keys(word: u64) -> [u32; 4] {
    let c0 = (word & 0xffff) as u32;
    let c1 = ((word >> 16) & 0xffff) as u32;
    let mode = u32::from(c0 > c1);
    let kr = (mode << 10) | ((c0 >> 11) << 5) | (c1 >> 11);
    let kg = (mode << 12) | (((c0 >> 5) & 63) << 6) | ((c1 >> 5) & 63);
    let kb = (mode << 10) | ((c0 & 31) << 5) | (c1 & 31);
    [kr, kg, kb, (word >> 32) as u32]
}

/// BC4's decoded values by the interpolation's numerator, for a channel of
/// maximum `max` and log range `log_range`: `(t7, t5)` with `t7[k]` the
/// value of `k / (7 · 255)` (8-level blocks) and `t5[k]` of `k / (5 · 255)`
/// (6-level blocks), each `max · e^{L (x − 1)}` in f32 and 0 at `x = 0`
/// (`bcdec_rs::bc4_float` then the codec's log scale). The CPU gather's
/// BC4 palettes read them; the GL gather uploads the same values.
pub fn bc4_levels(max: f32, log_range: f32) -> ([f32; 1786], [f32; 1276]) {
    let value = |x: f32| {
        if x <= 0.0 {
            0.0
        } else {
            max * (log_range * (x - 1.0)).exp()
        }
    };
    let mut t7 = [0.0f32; 1786];
    for (k, v) in t7.iter_mut().enumerate() {
        *v = value(k as f32 / (7.0 * 255.0));
    }
    let mut t5 = [0.0f32; 1276];
    for (k, v) in t5.iter_mut().enumerate() {
        *v = value(k as f32 / (5.0 * 255.0));
    }
    (t7, t5)
}
