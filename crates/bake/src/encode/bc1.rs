//! BC1 (DXT1) blocks of the log bytes: the ISPC encoder's blocks checked
//! and refined so that exact zeros stay zero (the codec module doc, step 3).

use super::TileCounts;

/// The texels (flat indices into the tile) of block (by, bx).
pub fn block_texels(by: usize, bx: usize, w: usize) -> [usize; 16] {
    std::array::from_fn(|p| (by * 4 + p / 4) * w + bx * 4 + p % 4)
}

/// BC1 of one tile of RGB log bytes, keeping black texels exactly black
/// (module doc): all-black blocks become all-zero blocks; mixed blocks are
/// encoded with their black texels replaced by the mean of the others, then
/// rewritten in 3-colour mode.
pub fn encode_bc1_tile(q: &[u8], h: usize, w: usize, counts: &mut TileCounts) -> Vec<u8> {
    let (bh, bw) = (h / 4, w / 4);
    let mut rgba = vec![255u8; h * w * 4];
    for (t, px) in q.chunks(3).enumerate() {
        rgba[t * 4..t * 4 + 3].copy_from_slice(px);
    }
    let is_black = |t: usize| q[t * 3] == 0 && q[t * 3 + 1] == 0 && q[t * 3 + 2] == 0;
    // Mean fill of the black texels of mixed blocks.
    let mut kinds = vec![0u8; bh * bw]; // 0: no black, 1: mixed, 2: all black
    for by in 0..bh {
        for bx in 0..bw {
            let texels = block_texels(by, bx, w);
            let blacks = texels.iter().filter(|&&t| is_black(t)).count();
            kinds[by * bw + bx] = match blacks {
                0 => 0,
                16 => 2,
                _ => 1,
            };
            if blacks > 0 && blacks < 16 {
                let mut sum = [0u32; 3];
                for &t in texels.iter().filter(|&&t| !is_black(t)) {
                    for c in 0..3 {
                        sum[c] += q[t * 3 + c] as u32;
                    }
                }
                let k = (16 - blacks) as u32;
                let mean = sum.map(|s| ((s + k / 2) / k) as u8);
                for &t in texels.iter().filter(|&&t| is_black(t)) {
                    rgba[t * 4..t * 4 + 3].copy_from_slice(&mean);
                }
            }
        }
    }
    let surface = intel_tex_2::RgbaSurface {
        data: &rgba,
        width: w as u32,
        height: h as u32,
        stride: (w * 4) as u32,
    };
    let mut blocks = intel_tex_2::bc1::compress_blocks(&surface);
    for (b, &kind) in kinds.iter().enumerate() {
        let block = &mut blocks[b * 8..b * 8 + 8];
        match kind {
            2 => block.fill(0),
            1 => {
                counts.mixed += 1;
                let texels = block_texels(b / bw, b % bw, w);
                let src: [[u8; 3]; 16] =
                    std::array::from_fn(|p| std::array::from_fn(|c| q[texels[p] * 3 + c]));
                let fixed = bc1_three_colour(block.try_into().unwrap(), &src);
                block.copy_from_slice(&fixed);
            }
            _ => {
                let texels = block_texels(b / bw, b % bw, w);
                let src: [[u8; 3]; 16] =
                    std::array::from_fn(|p| std::array::from_fn(|c| q[texels[p] * 3 + c]));
                let fixed = bc1_four_colour(block.try_into().unwrap(), &src);
                block.copy_from_slice(&fixed);
            }
        }
    }
    blocks
}

/// A 4-colour-mode BC1 block for `src` (no black texels to keep) with
/// endpoints `a`, `b`: ordered `c0 > c1`, each texel at the nearest palette
/// colour (ties to the lower index). Equal endpoints give a one-colour
/// block (all indices 0, which is `c0` in either mode). Returns the block,
/// its indices and its squared error.
fn bc1_build4(a: u16, b: u16, src: &[[u8; 3]; 16]) -> ([u8; 8], [u8; 16], u64) {
    let (c0, c1) = (a.max(b), a.min(b));
    let pal = bc1_palette(c0, c1);
    let mut idx = [0u8; 16];
    let mut sse = 0u64;
    for (p, px) in src.iter().enumerate() {
        let err = |k: usize| -> u64 {
            (0..3)
                .map(|c| (px[c] as i64 - pal[k][c] as i64).pow(2) as u64)
                .sum()
        };
        let best = if c0 == c1 {
            0
        } else {
            (0..4).min_by_key(|&k| (err(k), k)).unwrap()
        };
        idx[p] = best as u8;
        sse += err(best);
    }
    (pack_bc1(c0, c1, &idx), idx, sse)
}

/// The encoder's block for a block without black texels, made safe and
/// refined: the encoder occasionally emits `c0 ≤ c1` (3-colour mode, whose
/// index 3 is black), so the block is rebuilt in 4-colour mode with its
/// endpoints; then up to two least-squares refits of the endpoints for the
/// palette `c0, c1, (2c0 + c1)/3, (c0 + 2c1)/3` given the indices, each
/// kept only if the block's squared error drops. Rounding the refitted
/// endpoints to the nearest 5:6:5 value also removes most of the encoder's
/// systematic bias (about −0.3 of a byte level in G and B on smooth data).
fn bc1_four_colour(ispc: [u8; 8], src: &[[u8; 3]; 16]) -> [u8; 8] {
    let e0 = u16::from_le_bytes([ispc[0], ispc[1]]);
    let e1 = u16::from_le_bytes([ispc[2], ispc[3]]);
    let (mut best, mut idx, mut sse) = bc1_build4(e0, e1, src);
    let weights = |k: u8| match k {
        0 => (1.0, 0.0),
        1 => (0.0, 1.0),
        2 => (2.0 / 3.0, 1.0 / 3.0),
        _ => (1.0 / 3.0, 2.0 / 3.0),
    };
    for _ in 0..2 {
        if sse == 0 {
            break;
        }
        let Some((c0, c1)) = least_squares_endpoints(src, &idx, weights, |_| true) else {
            break;
        };
        let (block, new_idx, new_sse) = bc1_build4(to_565(c0), to_565(c1), src);
        if new_sse < sse {
            best = block;
            idx = new_idx;
            sse = new_sse;
        } else {
            break;
        }
    }
    best
}

/// Least-squares endpoints `(c0, c1)` (byte units, per channel) for the
/// texels of `src` that `used` accepts, given their indices and the weights
/// `(w0, w1)` of each index: minimises `Σ |x − (w0 c0 + w1 c1)|²`. When the
/// system is singular (one palette colour for every texel) both endpoints
/// are the mean; `None` when no texel is used.
fn least_squares_endpoints(
    src: &[[u8; 3]; 16],
    idx: &[u8; 16],
    weights: impl Fn(u8) -> (f64, f64),
    used: impl Fn(u8) -> bool,
) -> Option<([f64; 3], [f64; 3])> {
    let (mut aa, mut ab, mut bb) = (0.0f64, 0.0f64, 0.0f64);
    let (mut ax, mut bx, mut sum) = ([0.0f64; 3], [0.0f64; 3], [0.0f64; 3]);
    let mut count = 0usize;
    for (p, px) in src.iter().enumerate() {
        if !used(idx[p]) {
            continue;
        }
        let (a, b) = weights(idx[p]);
        aa += a * a;
        ab += a * b;
        bb += b * b;
        count += 1;
        for c in 0..3 {
            ax[c] += a * px[c] as f64;
            bx[c] += b * px[c] as f64;
            sum[c] += px[c] as f64;
        }
    }
    if count == 0 {
        return None;
    }
    let det = aa * bb - ab * ab;
    if det.abs() > 1e-9 {
        Some((
            std::array::from_fn(|c| (bb * ax[c] - ab * bx[c]) / det),
            std::array::from_fn(|c| (aa * bx[c] - ab * ax[c]) / det),
        ))
    } else {
        let m = sum.map(|v| v / count as f64);
        Some((m, m))
    }
}

/// The 4 palette colours of a BC1 block with endpoints `c0`, `c1`, as
/// `bcdec_rs` decodes them.
fn bc1_palette(c0: u16, c1: u16) -> [[u8; 3]; 4] {
    let mut block = [0u8; 8];
    block[0..2].copy_from_slice(&c0.to_le_bytes());
    block[2..4].copy_from_slice(&c1.to_le_bytes());
    // Texels 0..3 take indices 0..3.
    block[4] = 0b1110_0100;
    let mut rgba = [0u8; 64];
    bcdec_rs::bc1(&block, &mut rgba, 16);
    std::array::from_fn(|k| [rgba[k * 4], rgba[k * 4 + 1], rgba[k * 4 + 2]])
}

/// A 3-colour-mode BC1 block for `src` with endpoints `a`, `b` (ordered so
/// that `c0 ≤ c1`): black texels take index 3 (exact black), the others the
/// nearest palette colour (black included, ties to the lower index).
/// Returns the block, its indices and its squared error.
fn bc1_build3(a: u16, b: u16, src: &[[u8; 3]; 16]) -> ([u8; 8], [u8; 16], u64) {
    let (c0, c1) = (a.min(b), a.max(b));
    let pal = bc1_palette(c0, c1);
    debug_assert_eq!(pal[3], [0, 0, 0]);
    let mut idx = [0u8; 16];
    let mut sse = 0u64;
    for (p, px) in src.iter().enumerate() {
        if *px == [0, 0, 0] {
            idx[p] = 3;
            continue;
        }
        let err = |k: usize| -> u64 {
            (0..3)
                .map(|c| (px[c] as i64 - pal[k][c] as i64).pow(2) as u64)
                .sum()
        };
        let best = (0..4).min_by_key(|&k| (err(k), k)).unwrap();
        idx[p] = best as u8;
        sse += err(best);
    }
    (pack_bc1(c0, c1, &idx), idx, sse)
}

/// A BC1 block: the two RGB565 endpoints, then 2-bit indices, texel 0 in
/// the lowest bits (the S3TC layout).
fn pack_bc1(c0: u16, c1: u16, idx: &[u8; 16]) -> [u8; 8] {
    let mut block = [0u8; 8];
    block[0..2].copy_from_slice(&c0.to_le_bytes());
    block[2..4].copy_from_slice(&c1.to_le_bytes());
    let bits = idx
        .iter()
        .enumerate()
        .fold(0u32, |acc, (p, &k)| acc | (k as u32) << (2 * p));
    block[4..8].copy_from_slice(&bits.to_le_bytes());
    block
}

/// Packs an RGB colour in [0, 255] (f64) to RGB565, rounding.
fn to_565(c: [f64; 3]) -> u16 {
    let r = (c[0] * 31.0 / 255.0).round().clamp(0.0, 31.0) as u16;
    let g = (c[1] * 63.0 / 255.0).round().clamp(0.0, 63.0) as u16;
    let b = (c[2] * 31.0 / 255.0).round().clamp(0.0, 31.0) as u16;
    (r << 11) | (g << 5) | b
}

/// Rewrites a mixed block in BC1's 3-colour mode (module doc): the
/// encoder's endpoints reordered, then up to two least-squares refits of
/// the endpoints for the palette `c0, c1, (c0 + c1)/2` given the current
/// indices, each kept only if the block's squared error drops.
fn bc1_three_colour(ispc: [u8; 8], src: &[[u8; 3]; 16]) -> [u8; 8] {
    let e0 = u16::from_le_bytes([ispc[0], ispc[1]]);
    let e1 = u16::from_le_bytes([ispc[2], ispc[3]]);
    let (mut best, mut idx, mut sse) = bc1_build3(e0, e1, src);
    let weights = |k: u8| match k {
        0 => (1.0, 0.0),
        1 => (0.0, 1.0),
        _ => (0.5, 0.5),
    };
    for _ in 0..2 {
        if sse == 0 {
            break;
        }
        // Texels at index 3 (black) do not constrain the endpoints.
        let Some((c0, c1)) = least_squares_endpoints(src, &idx, weights, |k| k < 3) else {
            break;
        };
        let (block, new_idx, new_sse) = bc1_build3(to_565(c0), to_565(c1), src);
        if new_sse < sse {
            best = block;
            idx = new_idx;
            sse = new_sse;
        } else {
            break;
        }
    }
    best
}
