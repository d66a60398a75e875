//! BC4 blocks of one channel's log bytes, with the 6-level mode that keeps
//! exact zeros (the codec module doc, BC4-log).

use super::bc1::block_texels;
use super::TileCounts;

/// BC4 of one tile, one plane per stored channel, keeping zero bytes
/// exactly zero: blocks whose zeros the encoder does not keep are rewritten
/// in 6-level mode (module doc).
pub fn encode_bc4_tile(
    q: &[u8],
    h: usize,
    w: usize,
    ch: usize,
    counts: &mut TileCounts,
) -> Vec<u8> {
    let (bh, bw) = (h / 4, w / 4);
    let mut out = Vec::with_capacity(ch * bh * bw * 8);
    let mut plane = vec![0u8; h * w];
    for c in 0..ch {
        for (t, v) in plane.iter_mut().enumerate() {
            *v = q[t * ch + c];
        }
        let surface = intel_tex_2::RSurface {
            data: &plane,
            width: w as u32,
            height: h as u32,
            stride: w as u32,
        };
        let mut blocks = intel_tex_2::bc4::compress_blocks(&surface);
        for b in 0..bh * bw {
            let texels = block_texels(b / bw, b % bw, w);
            let src: [u8; 16] = std::array::from_fn(|p| plane[texels[p]]);
            let block = &mut blocks[b * 8..b * 8 + 8];
            if src.iter().all(|&v| v == 0) {
                block.fill(0);
                continue;
            }
            if !src.contains(&0) {
                continue;
            }
            // Mixed: the encoder's block is kept only if it keeps the zeros
            // and beats the best 6-level block.
            counts.mixed += 1;
            let six = bc4_six_level(&src);
            let ispc: [u8; 8] = block.try_into().unwrap();
            let better = match (bc4_sse(&ispc, &src), bc4_sse(&six, &src)) {
                (Some(a), Some(b)) => a <= b,
                (Some(_), None) => true,
                _ => false,
            };
            if !better {
                block.copy_from_slice(&six);
            }
        }
        out.extend_from_slice(&blocks);
    }
    out
}

/// The squared error (in byte units) of a BC4 block against `src`, `None`
/// if a zero byte of `src` decodes nonzero.
fn bc4_sse(block: &[u8; 8], src: &[u8; 16]) -> Option<f64> {
    let mut dec = [0.0f32; 16];
    bcdec_rs::bc4_float(block, &mut dec, 4, false);
    let mut sse = 0.0f64;
    for (&s, &d) in src.iter().zip(&dec) {
        if s == 0 && d != 0.0 {
            return None;
        }
        sse += (d as f64 * 255.0 - s as f64).powi(2);
    }
    Some(sse)
}

/// A BC4 block in 6-level mode (`r0 ≤ r1`) for bytes with zeros: zeros at
/// index 6 (exactly 0), the others at the nearest of the 8 levels (ties to
/// the lower index); the endpoints are searched within ±2 of the smallest
/// and largest nonzero byte for the least squared error (ties to the first
/// found), so the result is deterministic.
fn bc4_six_level(src: &[u8; 16]) -> [u8; 8] {
    let nz = src.iter().filter(|&&v| v > 0);
    let lo = nz.clone().min().copied().unwrap_or(0) as i32;
    let hi = nz.max().copied().unwrap_or(0) as i32;
    let mut best = ([0u8; 8], f64::INFINITY);
    for r0 in (lo - 2).max(0)..=(lo + 2).min(255) {
        for r1 in (hi - 2).max(r0)..=(hi + 2).min(255) {
            let block = bc4_six_level_with(src, r0 as u8, r1 as u8);
            let sse = bc4_sse(&block, src).expect("6-level blocks keep zeros");
            if sse < best.1 {
                best = (block, sse);
            }
        }
    }
    best.0
}

/// The 6-level block with endpoints `r0 ≤ r1` and nearest-level indices.
fn bc4_six_level_with(src: &[u8; 16], r0: u8, r1: u8) -> [u8; 8] {
    let (a, b) = (r0 as f64, r1 as f64);
    let levels: [f64; 8] = [
        a,
        b,
        (4.0 * a + b) / 5.0,
        (3.0 * a + 2.0 * b) / 5.0,
        (2.0 * a + 3.0 * b) / 5.0,
        (a + 4.0 * b) / 5.0,
        0.0,
        255.0,
    ];
    let mut bits = 0u64;
    for (p, &v) in src.iter().enumerate() {
        let k = if v == 0 {
            6
        } else {
            (0..8)
                .min_by(|&x, &y| {
                    let (dx, dy) = ((levels[x] - v as f64).abs(), (levels[y] - v as f64).abs());
                    dx.partial_cmp(&dy).unwrap().then(x.cmp(&y))
                })
                .unwrap()
        };
        bits |= (k as u64) << (3 * p);
    }
    let mut block = [0u8; 8];
    block[0] = r0;
    block[1] = r1;
    block[2..8].copy_from_slice(&bits.to_le_bytes()[..6]);
    block
}
