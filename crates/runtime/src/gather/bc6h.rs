//! BC6H for the CPU gather: each block unpacked once, at load, into a form
//! whose decoding is plain arithmetic that vectorises (its unquantized
//! endpoints, per-texel weights and region mask: [`UNPACKED_BYTES`] bytes
//! instead of 16), then decoded and multiplied per block column in every
//! frame.
//!
//! BC6H's cost on the CPU is its header: 14 modes, each scattering its
//! endpoints' bits differently over the block's first 65 or 82 bits, some
//! of them reversed, with delta endpoints to sign-extend and add, and index
//! fields whose anchors have one bit less (the D3D11 "BC6H Format"
//! specification). Decoding that per block and frame took about 140 of the
//! 190 cycles a block cost (the Cornell box at 2,069 patches, `bcdec_rs`).
//! What remains per texel is the specification's interpolation of the
//! unquantized endpoints `e0`, `e1` with the index's weight `w` (in 64ths),
//! `x = (e0 (64 − w) + e1 w + 32) >> 6`, and its scaling to a half float's
//! bits, `(31 x) >> 6` (unsigned BC6H, the only kind the codec writes): a
//! few integer operations per texel and channel, the same for every mode.
//!
//! The unpacked block is decoded bit for bit as `bcdec_rs::bc6h_half`
//! decodes the packed one (the module's test compares them on random blocks
//! of every mode, the reserved modes, which decode to zero, included).
//! Its size makes a BC6H matrix 2.75 bytes per entry in memory at run time
//! (the file keeps 1).

/// Bytes of one unpacked block: 12 endpoints (`u16`: region 0's `e0` then
/// `e1` as red, green, blue, then region 1's), 16 weights (`u8`, texel
/// `t = 4 y + x`) and the region mask (`u16`, bit `t` set where texel `t`
/// is in region 1; a one-region block's mask is 0), little endian.
pub const UNPACKED_BYTES: usize = 44;

/// Endpoint field of a mode's header: `w`, `x`, `y`, `z` of red, green and
/// blue (`w`, `x`: region 0's endpoints; `y`, `z`: region 1's), and the
/// partition `d`.
const RW: u8 = 0;
const GW: u8 = 1;
const BW: u8 = 2;
const RX: u8 = 3;
const GX: u8 = 4;
const BX: u8 = 5;
const RY: u8 = 6;
const GY: u8 = 7;
const BY: u8 = 8;
const RZ: u8 = 9;
const GZ: u8 = 10;
const BZ: u8 = 11;
const D: u8 = 12;

/// One run of a header's bits: the block's next bits, in stream order, go
/// to field `.0`'s bits `.1`, then towards `.2` (`.1 > .2`: a reversed
/// run, as the specification's `rw[10:15]`).
type Run = (u8, u8, u8);

/// A mode: its code (the block's first 2 or 5 bits), the bits of its base
/// endpoint `w` and of its red, green and blue `x`, `y`, `z`, whether those
/// are deltas from `w`, and its header after the mode bits (the D3D11
/// specification's table of BC6H modes, modes 1 to 14 in its order).
struct Mode {
    code: u32,
    code_bits: u32,
    base_bits: u32,
    delta_bits: [u32; 3],
    deltas: bool,
    header: &'static [Run],
}

const MODES: [Mode; 14] = [
    Mode {
        code: 0b00,
        code_bits: 2,
        base_bits: 10,
        delta_bits: [5, 5, 5],
        deltas: true,
        header: &[
            (GY, 4, 4),
            (BY, 4, 4),
            (BZ, 4, 4),
            (RW, 0, 9),
            (GW, 0, 9),
            (BW, 0, 9),
            (RX, 0, 4),
            (GZ, 4, 4),
            (GY, 0, 3),
            (GX, 0, 4),
            (BZ, 0, 0),
            (GZ, 0, 3),
            (BX, 0, 4),
            (BZ, 1, 1),
            (BY, 0, 3),
            (RY, 0, 4),
            (BZ, 2, 2),
            (RZ, 0, 4),
            (BZ, 3, 3),
            (D, 0, 4),
        ],
    },
    Mode {
        code: 0b01,
        code_bits: 2,
        base_bits: 7,
        delta_bits: [6, 6, 6],
        deltas: true,
        header: &[
            (GY, 5, 5),
            (GZ, 4, 4),
            (GZ, 5, 5),
            (RW, 0, 6),
            (BZ, 0, 0),
            (BZ, 1, 1),
            (BY, 4, 4),
            (GW, 0, 6),
            (BY, 5, 5),
            (BZ, 2, 2),
            (GY, 4, 4),
            (BW, 0, 6),
            (BZ, 3, 3),
            (BZ, 5, 5),
            (BZ, 4, 4),
            (RX, 0, 5),
            (GY, 0, 3),
            (GX, 0, 5),
            (GZ, 0, 3),
            (BX, 0, 5),
            (BY, 0, 3),
            (RY, 0, 5),
            (RZ, 0, 5),
            (D, 0, 4),
        ],
    },
    Mode {
        code: 0b00010,
        code_bits: 5,
        base_bits: 11,
        delta_bits: [5, 4, 4],
        deltas: true,
        header: &[
            (RW, 0, 9),
            (GW, 0, 9),
            (BW, 0, 9),
            (RX, 0, 4),
            (RW, 10, 10),
            (GY, 0, 3),
            (GX, 0, 3),
            (GW, 10, 10),
            (BZ, 0, 0),
            (GZ, 0, 3),
            (BX, 0, 3),
            (BW, 10, 10),
            (BZ, 1, 1),
            (BY, 0, 3),
            (RY, 0, 4),
            (BZ, 2, 2),
            (RZ, 0, 4),
            (BZ, 3, 3),
            (D, 0, 4),
        ],
    },
    Mode {
        code: 0b00110,
        code_bits: 5,
        base_bits: 11,
        delta_bits: [4, 5, 4],
        deltas: true,
        header: &[
            (RW, 0, 9),
            (GW, 0, 9),
            (BW, 0, 9),
            (RX, 0, 3),
            (RW, 10, 10),
            (GZ, 4, 4),
            (GY, 0, 3),
            (GX, 0, 4),
            (GW, 10, 10),
            (GZ, 0, 3),
            (BX, 0, 3),
            (BW, 10, 10),
            (BZ, 1, 1),
            (BY, 0, 3),
            (RY, 0, 3),
            (BZ, 0, 0),
            (BZ, 2, 2),
            (RZ, 0, 3),
            (GY, 4, 4),
            (BZ, 3, 3),
            (D, 0, 4),
        ],
    },
    Mode {
        code: 0b01010,
        code_bits: 5,
        base_bits: 11,
        delta_bits: [4, 4, 5],
        deltas: true,
        header: &[
            (RW, 0, 9),
            (GW, 0, 9),
            (BW, 0, 9),
            (RX, 0, 3),
            (RW, 10, 10),
            (BY, 4, 4),
            (GY, 0, 3),
            (GX, 0, 3),
            (GW, 10, 10),
            (BZ, 0, 0),
            (GZ, 0, 3),
            (BX, 0, 4),
            (BW, 10, 10),
            (BY, 0, 3),
            (RY, 0, 3),
            (BZ, 1, 1),
            (BZ, 2, 2),
            (RZ, 0, 3),
            (BZ, 4, 4),
            (BZ, 3, 3),
            (D, 0, 4),
        ],
    },
    Mode {
        code: 0b01110,
        code_bits: 5,
        base_bits: 9,
        delta_bits: [5, 5, 5],
        deltas: true,
        header: &[
            (RW, 0, 8),
            (BY, 4, 4),
            (GW, 0, 8),
            (GY, 4, 4),
            (BW, 0, 8),
            (BZ, 4, 4),
            (RX, 0, 4),
            (GZ, 4, 4),
            (GY, 0, 3),
            (GX, 0, 4),
            (BZ, 0, 0),
            (GZ, 0, 3),
            (BX, 0, 4),
            (BZ, 1, 1),
            (BY, 0, 3),
            (RY, 0, 4),
            (BZ, 2, 2),
            (RZ, 0, 4),
            (BZ, 3, 3),
            (D, 0, 4),
        ],
    },
    Mode {
        code: 0b10010,
        code_bits: 5,
        base_bits: 8,
        delta_bits: [6, 5, 5],
        deltas: true,
        header: &[
            (RW, 0, 7),
            (GZ, 4, 4),
            (BY, 4, 4),
            (GW, 0, 7),
            (BZ, 2, 2),
            (GY, 4, 4),
            (BW, 0, 7),
            (BZ, 3, 3),
            (BZ, 4, 4),
            (RX, 0, 5),
            (GY, 0, 3),
            (GX, 0, 4),
            (BZ, 0, 0),
            (GZ, 0, 3),
            (BX, 0, 4),
            (BZ, 1, 1),
            (BY, 0, 3),
            (RY, 0, 5),
            (RZ, 0, 5),
            (D, 0, 4),
        ],
    },
    Mode {
        code: 0b10110,
        code_bits: 5,
        base_bits: 8,
        delta_bits: [5, 6, 5],
        deltas: true,
        header: &[
            (RW, 0, 7),
            (BZ, 0, 0),
            (BY, 4, 4),
            (GW, 0, 7),
            (GY, 5, 5),
            (GY, 4, 4),
            (BW, 0, 7),
            (GZ, 5, 5),
            (BZ, 4, 4),
            (RX, 0, 4),
            (GZ, 4, 4),
            (GY, 0, 3),
            (GX, 0, 5),
            (GZ, 0, 3),
            (BX, 0, 4),
            (BZ, 1, 1),
            (BY, 0, 3),
            (RY, 0, 4),
            (BZ, 2, 2),
            (RZ, 0, 4),
            (BZ, 3, 3),
            (D, 0, 4),
        ],
    },
    Mode {
        code: 0b11010,
        code_bits: 5,
        base_bits: 8,
        delta_bits: [5, 5, 6],
        deltas: true,
        header: &[
            (RW, 0, 7),
            (BZ, 1, 1),
            (BY, 4, 4),
            (GW, 0, 7),
            (BY, 5, 5),
            (GY, 4, 4),
            (BW, 0, 7),
            (BZ, 5, 5),
            (BZ, 4, 4),
            (RX, 0, 4),
            (GZ, 4, 4),
            (GY, 0, 3),
            (GX, 0, 4),
            (BZ, 0, 0),
            (GZ, 0, 3),
            (BX, 0, 5),
            (BY, 0, 3),
            (RY, 0, 4),
            (BZ, 2, 2),
            (RZ, 0, 4),
            (BZ, 3, 3),
            (D, 0, 4),
        ],
    },
    Mode {
        code: 0b11110,
        code_bits: 5,
        base_bits: 6,
        delta_bits: [6, 6, 6],
        deltas: false,
        header: &[
            (RW, 0, 5),
            (GZ, 4, 4),
            (BZ, 0, 0),
            (BZ, 1, 1),
            (BY, 4, 4),
            (GW, 0, 5),
            (GY, 5, 5),
            (BY, 5, 5),
            (BZ, 2, 2),
            (GY, 4, 4),
            (BW, 0, 5),
            (GZ, 5, 5),
            (BZ, 3, 3),
            (BZ, 5, 5),
            (BZ, 4, 4),
            (RX, 0, 5),
            (GY, 0, 3),
            (GX, 0, 5),
            (GZ, 0, 3),
            (BX, 0, 5),
            (BY, 0, 3),
            (RY, 0, 5),
            (RZ, 0, 5),
            (D, 0, 4),
        ],
    },
    Mode {
        code: 0b00011,
        code_bits: 5,
        base_bits: 10,
        delta_bits: [10, 10, 10],
        deltas: false,
        header: &[
            (RW, 0, 9),
            (GW, 0, 9),
            (BW, 0, 9),
            (RX, 0, 9),
            (GX, 0, 9),
            (BX, 0, 9),
        ],
    },
    Mode {
        code: 0b00111,
        code_bits: 5,
        base_bits: 11,
        delta_bits: [9, 9, 9],
        deltas: true,
        header: &[
            (RW, 0, 9),
            (GW, 0, 9),
            (BW, 0, 9),
            (RX, 0, 8),
            (RW, 10, 10),
            (GX, 0, 8),
            (GW, 10, 10),
            (BX, 0, 8),
            (BW, 10, 10),
        ],
    },
    Mode {
        code: 0b01011,
        code_bits: 5,
        base_bits: 12,
        delta_bits: [8, 8, 8],
        deltas: true,
        header: &[
            (RW, 0, 9),
            (GW, 0, 9),
            (BW, 0, 9),
            (RX, 0, 7),
            (RW, 11, 10),
            (GX, 0, 7),
            (GW, 11, 10),
            (BX, 0, 7),
            (BW, 11, 10),
        ],
    },
    Mode {
        code: 0b01111,
        code_bits: 5,
        base_bits: 16,
        delta_bits: [4, 4, 4],
        deltas: true,
        header: &[
            (RW, 0, 9),
            (GW, 0, 9),
            (BW, 0, 9),
            (RX, 0, 3),
            (RW, 15, 10),
            (GX, 0, 3),
            (GW, 15, 10),
            (BX, 0, 3),
            (BW, 15, 10),
        ],
    },
];

/// The 32 two-region partitions (the specification's table, shared with
/// BC7): bit `t` set where texel `t` is in region 1.
const PARTITIONS: [u16; 32] = [
    0xcccc, 0x8888, 0xeeee, 0xecc8, 0xc880, 0xfeec, 0xfec8, 0xec80, 0xc800, 0xffec, 0xfe80, 0xe800,
    0xffe8, 0xff00, 0xfff0, 0xf000, 0xf710, 0x008e, 0x7100, 0x08ce, 0x008c, 0x7310, 0x3100, 0x8cce,
    0x088c, 0x3110, 0x6666, 0x366c, 0x17e8, 0x0ff0, 0x718e, 0x399c,
];

/// Region 1's anchor texel per partition (its index has one bit less;
/// region 0's anchor is texel 0).
const ANCHORS: [u8; 32] = [
    15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 15, 2, 8, 2, 2, 8, 8, 15, 2, 8,
    2, 2, 8, 8, 2, 2,
];

/// The interpolation weights of 3- and 4-bit indices, in 64ths.
const WEIGHTS3: [u8; 8] = [0, 9, 18, 27, 37, 46, 55, 64];
const WEIGHTS4: [u8; 16] = [0, 4, 9, 13, 17, 21, 26, 30, 34, 38, 43, 47, 51, 55, 60, 64];

/// The block's bits from `at` on, `n ≤ 32` of them.
fn bits(block: u128, at: u32, n: u32) -> u32 {
    ((block >> at) as u32) & ((1u64 << n) - 1) as u32
}

/// `v`'s low `n` bits as a signed number.
fn sign_extend(v: u32, n: u32) -> i32 {
    ((v << (32 - n)) as i32) >> (32 - n)
}

/// The specification's unquantization of an unsigned endpoint of `n` bits
/// to 16.
fn unquantize(v: u32, n: u32) -> u16 {
    if n >= 15 || v == 0 {
        v as u16
    } else if v == (1 << n) - 1 {
        0xffff
    } else {
        (((v << 16) + 0x8000) >> n) as u16
    }
}

/// Appends the unpacked form (module doc) of the unsigned BC6H block
/// `packed` to `out`.
pub fn unpack(packed: &[u8; 16], out: &mut Vec<u8>) {
    let block = u128::from_le_bytes(*packed);
    let short = bits(block, 0, 2);
    let code = if short < 2 { short } else { bits(block, 0, 5) };
    let Some(mode) = MODES
        .iter()
        .find(|m| m.code == code && (m.code_bits == 2) == (short < 2))
    else {
        // A reserved mode: every texel decodes to zero.
        out.extend_from_slice(&[0; UNPACKED_BYTES]);
        return;
    };
    let mut field = [0u32; 13];
    let mut at = mode.code_bits;
    for &(f, first, last) in mode.header {
        let step: i32 = if last >= first { 1 } else { -1 };
        let mut k = first as i32;
        loop {
            field[f as usize] |= bits(block, at, 1) << k;
            at += 1;
            if k == last as i32 {
                break;
            }
            k += step;
        }
    }
    // Two regions: the modes whose header ends with the partition.
    let two = mode.header.last().is_some_and(|r| r.0 == D);
    debug_assert_eq!(at, if two { 82 } else { 65 });
    let n = mode.base_bits;
    let mask = (1u32 << n) - 1;
    // Endpoints by field index: w (base), then x, y, z of each channel.
    let mut ep = [0u16; 12];
    for c in 0..3 {
        let w = field[c];
        let others = if two { 3 } else { 1 };
        let mut e = [w, 0, 0, 0];
        for (k, v) in e.iter_mut().enumerate().skip(1).take(others) {
            let raw = field[3 * k + c];
            *v = if mode.deltas {
                (w as i32 + sign_extend(raw, mode.delta_bits[c])) as u32 & mask
            } else {
                raw
            };
        }
        // Region 0: w, x; region 1: y, z.
        for (k, &v) in e.iter().enumerate() {
            ep[3 * k + c] = unquantize(v, n);
        }
    }
    let (region_mask, anchor) = if two {
        let d = field[D as usize] as usize;
        (PARTITIONS[d], ANCHORS[d] as usize)
    } else {
        (0, 0)
    };
    let mut weights = [0u8; 16];
    let mut at = if two { 82 } else { 65 };
    for (t, w) in weights.iter_mut().enumerate() {
        let full = if two { 3 } else { 4 };
        let nb = if t == 0 || (two && t == anchor) {
            full - 1
        } else {
            full
        };
        let idx = bits(block, at, nb) as usize;
        at += nb;
        *w = if two { WEIGHTS3[idx] } else { WEIGHTS4[idx] };
    }
    for v in ep {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out.extend_from_slice(&weights);
    out.extend_from_slice(&region_mask.to_le_bytes());
    out.extend_from_slice(&[0, 0]);
}

/// The half float bits `h` (finite, non-negative: what unsigned BC6H
/// decodes to) as an f32, in integer arithmetic and one exact conversion
/// (no subnormal f32 operand, which some CPUs handle slowly), both cases
/// computed and one selected, so that a loop of it vectorises.
#[inline(always)]
fn half_to_f32(h: u32) -> f32 {
    // Subnormal half: h · 2⁻²⁴, exact; normal: the exponent rebased.
    let sub = h as i32 as f32 * (1.0 / 16_777_216.0);
    let normal = f32::from_bits((h << 13).wrapping_add(112 << 23));
    if h < 0x400 {
        sub
    } else {
        normal
    }
}

/// One unpacked block (`u`) decoded and multiplied by `b` into `acc`
/// (three channels), lane `t` for texel `t`: the specification's
/// interpolation and scaling, as `bcdec_rs::bc6h_half` computes them.
/// Written as straight loops over 16 lanes, without branches, so that the
/// compiler vectorises them.
#[inline(always)]
fn block(u: &[u8], b: &[[f32; 4]; 3], acc: &mut [[f32; 16]; 3]) {
    let ep: [i32; 12] =
        std::array::from_fn(|k| u16::from_le_bytes([u[2 * k], u[2 * k + 1]]) as i32);
    let w: [i32; 16] = std::array::from_fn(|t| u[24 + t] as i32);
    let mask = u16::from_le_bytes([u[40], u[41]]) as i32;
    // All ones in region 1's lanes.
    let region: [i32; 16] = std::array::from_fn(|t| -((mask >> t) & 1));
    for (c, (a, b)) in acc.iter_mut().zip(b).enumerate() {
        let (a0, a1, c0, c1) = (ep[c], ep[3 + c], ep[6 + c], ep[9 + c]);
        let mut f = [0.0f32; 16];
        for t in 0..16 {
            let e0 = a0 ^ ((a0 ^ c0) & region[t]);
            let e1 = a1 ^ ((a1 ^ c1) & region[t]);
            // e0 (64 − w) + e1 w, as e0 · 64 + (e1 − e0) w.
            let x = ((e0 << 6) + (e1 - e0) * w[t] + 32) >> 6;
            f[t] = half_to_f32(((x * 31) >> 6) as u32);
        }
        for t in 0..16 {
            a[t] += f[t] * b[t & 3];
        }
    }
}

/// A block column of unpacked blocks (`acc.len()` block rows) times `b`
/// (its 4 columns of `B0` per channel, the codec's scale folded in) into
/// `acc`, portable.
pub(super) fn column(col: &[u8], b: &[[f32; 4]; 3], acc: &mut [[[f32; 16]; 3]]) {
    for (u, a) in col.chunks_exact(UNPACKED_BYTES).zip(acc.iter_mut()) {
        block(u, b, a);
    }
}

/// [`column`] compiled for AVX-512: the same Rust, so the same operations
/// in the same order and the same bits, in 16-lane vectors.
///
/// # Safety
/// The CPU must have AVX-512F.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
pub(super) unsafe fn column_avx512(col: &[u8], b: &[[f32; 4]; 3], acc: &mut [[[f32; 16]; 3]]) {
    for (u, a) in col.chunks_exact(UNPACKED_BYTES).zip(acc.iter_mut()) {
        block(u, b, a);
    }
}

/// [`column`] compiled for AVX2, as [`column_avx512`].
///
/// # Safety
/// The CPU must have AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn column_avx2(col: &[u8], b: &[[f32; 4]; 3], acc: &mut [[[f32; 16]; 3]]) {
    for (u, a) in col.chunks_exact(UNPACKED_BYTES).zip(acc.iter_mut()) {
        block(u, b, a);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use half::f16;

    /// Random blocks (every mode's code forced in turn, and fully random
    /// ones, which hit the reserved codes too), unpacked and gathered with
    /// `B0 = 1` into zeros by every kernel this CPU runs: each lane is the
    /// value `bcdec_rs` decodes, bit for bit.
    #[test]
    fn unpacked_blocks_decode_as_bcdec_does() {
        let mut rng = radiosity_core::math::SplitMix64::new(6);
        let mut word = || {
            let lo = (rng.uniform() * 4294967296.0) as u128;
            let hi = (rng.uniform() * 4294967296.0) as u128;
            lo | hi << 32
        };
        let codes: Vec<(u128, u128)> = MODES
            .iter()
            .map(|m| (m.code as u128, (1u128 << m.code_bits) - 1))
            .chain([(0, 0)])
            .chain([19u128, 23, 27, 31].map(|c| (c, 31)))
            .collect();
        type Kernel = fn(&[u8], &[[f32; 4]; 3], &mut [[[f32; 16]; 3]]);
        let mut kernels: Vec<(&str, Kernel)> = vec![("portable", column)];
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx512f") {
                // SAFETY: checked just above.
                kernels.push(("avx512", |c, b, a| unsafe { column_avx512(c, b, a) }));
            }
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: checked just above.
                kernels.push(("avx2", |c, b, a| unsafe { column_avx2(c, b, a) }));
            }
        }
        let ones = [[1.0f32; 4]; 3];
        let mut out = Vec::new();
        let mut modes_with_values = 0;
        for &(code, code_mask) in &codes {
            let mut nonzero = false;
            for _ in 0..20_000 {
                let block = (word() | word() << 64) & !code_mask | code;
                let packed = block.to_le_bytes();
                let mut want = [0u16; 48];
                bcdec_rs::bc6h_half(&packed, &mut want, 12, false);
                nonzero |= want.iter().any(|&h| h != 0);
                out.clear();
                unpack(&packed, &mut out);
                assert_eq!(out.len(), UNPACKED_BYTES);
                for (name, kernel) in &kernels {
                    let mut acc = [[[0.0f32; 16]; 3]];
                    kernel(&out, &ones, &mut acc);
                    for t in 0..16 {
                        for c in 0..3 {
                            let w = f16::from_bits(want[3 * t + c]).to_f32();
                            assert_eq!(
                                acc[0][c][t].to_bits(),
                                w.to_bits(),
                                "{name}: block {block:#034x}, texel {t}, channel {c}"
                            );
                        }
                    }
                }
            }
            modes_with_values += usize::from(nonzero);
        }
        // The 14 modes and the random codes decode to something.
        assert_eq!(modes_with_values, 15);
    }

    /// Every half a block can decode to (`0 ..= 0x7bff`) converts exactly.
    #[test]
    fn half_bits_convert_exactly() {
        for h in 0..=0x7bffu32 {
            assert_eq!(
                half_to_f32(h).to_bits(),
                f16::from_bits(h as u16).to_f32().to_bits()
            );
        }
    }
}
