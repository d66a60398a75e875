//! The x86-64 kernels of the CPU gather ([`super`]): a BC1 row of tiles
//! on AVX-512 and on AVX2 + FMA, and the sparse part's RGB9E5 loop on
//! AVX2. Each computes what the portable code beside it computes
//! ([`super::bc1`], [`super::bc4`], [`super::sparse`]): the sparse loop
//! with the same bits, the BC1 rows within f32 rounding of the portable
//! order (both vector paths add in one order). They are tested against the
//! portable path (`tests/gather.rs`, the unit test in `sparse.rs`).

use super::palette::{bc1_keys, Bc1Table};
use super::rows::{tile_columns, Rows};

/// [`super::sparse`]'s RGB9E5 loop with AVX2 (the runs of a row of tiles in one
/// call): the three mantissas extracted by one variable shift and
/// converted together; the same operations per lane in the same order
/// (mantissa times factor, times `B0`, added to the row), so the same
/// bits. 20 instructions an entry (no bounds check: [`Rows`] and
/// [`tile_columns`]), where the portable loop, which
/// the compiler vectorises only partly, took 41 with its checks (counted
/// in the disassembly).
#[target_feature(enable = "avx2")]
pub(super) unsafe fn sparse_rgb9e5_avx2(
    runs: &[[u32; 3]],
    pos: &[u16],
    packed: &[u32],
    exp_factor: &[[f32; 4]; 32],
    b0x: &[[f32; 4]],
    rows: &mut Rows,
) {
    use std::arch::x86_64::*;
    let shifts = _mm_setr_epi32(0, 9, 18, 0);
    let mask = _mm_setr_epi32(0x1ff, 0x1ff, 0x1ff, 0);
    for (i, &[a, b, jb]) in runs.iter().enumerate() {
        if let Some(&[next, _, _]) = runs.get(i + SPARSE_PREFETCH_AHEAD) {
            let next = next as usize;
            _mm_prefetch::<_MM_HINT_T0>(pos.as_ptr().wrapping_add(next).cast());
            _mm_prefetch::<_MM_HINT_T0>(packed.as_ptr().wrapping_add(next).cast());
        }
        let (a, b) = (a as usize, b as usize);
        let b0x = tile_columns(b0x, jb);
        for (&p, &w) in pos[a..b].iter().zip(&packed[a..b]) {
            let m = _mm_cvtepi32_ps(_mm_and_si128(
                _mm_srlv_epi32(_mm_set1_epi32(w as i32), shifts),
                mask,
            ));
            let f = _mm_loadu_ps(exp_factor[(w >> 27) as usize].as_ptr());
            let b = _mm_loadu_ps(b0x[(p & 0xff) as usize].as_ptr());
            let row = rows[(p >> 8) as usize].as_mut_ptr();
            _mm_storeu_ps(
                row,
                _mm_add_ps(_mm_loadu_ps(row), _mm_mul_ps(_mm_mul_ps(m, f), b)),
            );
        }
    }
}

/// How many runs ahead [`sparse_rgb9e5_avx2`] prefetches their first
/// entries.
const SPARSE_PREFETCH_AHEAD: usize = 4;

/// How many active block columns ahead [`bc1_row_avx512`] prefetches:
/// enough lines in flight to cover a memory latency of ~100 ns at the
/// ~10 ns one column takes to decode.
const PREFETCH_AHEAD: usize = 16;

/// How many active block columns [`bc1_row_avx512`] decodes the keys of
/// before their multiply-adds: 64 columns are 8 KiB of keys, in L1 while
/// they are read back (and long stored, so no load waits on a store).
pub(super) const AVX512_SEGMENT: usize = 64;

/// A BC1 row of tiles of `BH` block rows on AVX-512, each block column
/// times its 4 values of `B0` (from [`super::columns::fill_b0_groups`]) into `acc`,
/// the `3 BH` accumulators held in registers for the whole row (24 of the
/// 32 vector registers for a full row). By segments of
/// [`AVX512_SEGMENT`] active block columns:
/// - the palette keys ([`bc1_keys`]) of a full column's 8 blocks are
///   computed at once in one vector (its 64 bytes: endpoints in the even
///   32-bit lanes, indices in the odd ones) and stored as two vectors per
///   column, block `k`'s red and green keys at lanes `2k`, `2k + 1` of
///   the first, its blue key and indices at `2k`, `2k + 1` of the second
///   (the scalar key arithmetic was most of the instructions per block);
/// - then per block: its indices broadcast from memory and shifted so that
///   lane `l`'s low two bits are entry `l`'s index, and per channel one
///   palette broadcast (4 values in every 128-bit lane), one `vpermps`
///   (which reads the low 4 bits of each index lane: with the palette in
///   every 128-bit lane, bits 2–3 pick one of four equal copies, so no
///   mask is needed) and one fused multiply-add.
///
/// A shorter last row of tiles (`BH < 8`, whose column is less than one
/// vector) computes the same keys with the scalar [`bc1_keys`]. Per
/// accumulator lane the columns are added in the same order as on AVX2.
#[target_feature(enable = "avx512f")]
pub(super) unsafe fn bc1_row_avx512<const BH: usize>(
    dense: &[u8],
    cols: &[(u32, u32)],
    b0p: &[[[f32; 4]; 3]],
    tables: &[Bc1Table; 3],
    keys: &mut Vec<[[u32; 16]; 2]>,
    acc: &mut [[[f32; 16]; 3]],
) {
    use std::arch::x86_64::*;
    let shifts = _mm512_setr_epi32(0, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 22, 24, 26, 28, 30);
    let mut a = [[_mm512_setzero_ps(); 3]; BH];
    for (k, row) in a.iter_mut().enumerate() {
        for (c, v) in row.iter_mut().enumerate() {
            *v = _mm512_loadu_ps(acc[k][c].as_ptr());
        }
    }
    let (t0, t1, t2) = (
        tables[0].values.as_ptr() as *const u8,
        tables[1].values.as_ptr() as *const u8,
        tables[2].values.as_ptr() as *const u8,
    );
    // Per column of the segment: [kr, kg] and [kb, idx] of its blocks
    // (byte offsets into the tables: keys times 16), in the caller's
    // buffer, kept between rows (a new one per row is 8 KiB to fill).
    keys.resize(AVX512_SEGMENT, [[0; 16]; 2]);
    let lo16 = _mm512_set1_epi32(0xffff);
    let (m5, m6) = (_mm512_set1_epi32(31), _mm512_set1_epi32(63));
    let (mode_rb, mode_g) = (_mm512_set1_epi32(1 << 10), _mm512_set1_epi32(1 << 12));
    for (si, seg) in cols.chunks(AVX512_SEGMENT).enumerate() {
        for (ci, &(off, _)) in seg.iter().enumerate() {
            // Skipped columns leave the active ones scattered: each is one
            // 64-byte line the hardware prefetcher does not predict. Ask
            // for the column PREFETCH_AHEAD places on now (a hint; no
            // effect on results).
            if let Some(&(next, _)) = cols.get(si * AVX512_SEGMENT + ci + PREFETCH_AHEAD) {
                _mm_prefetch::<_MM_HINT_T0>(dense.as_ptr().add(next as usize) as *const i8);
            }
            let col = dense.as_ptr().add(off as usize);
            let out = &mut keys[ci];
            if BH == 8 {
                let w = _mm512_loadu_si512(col as *const __m512i);
                let c0 = _mm512_and_si512(w, lo16);
                let c1 = _mm512_srli_epi32::<16>(w);
                let mode = _mm512_cmpgt_epu32_mask(c0, c1);
                let kr = _mm512_or_si512(
                    _mm512_slli_epi32::<5>(_mm512_srli_epi32::<11>(c0)),
                    _mm512_srli_epi32::<11>(c1),
                );
                let kr = _mm512_mask_or_epi32(kr, mode, kr, mode_rb);
                let kg = _mm512_or_si512(
                    _mm512_slli_epi32::<6>(_mm512_and_si512(_mm512_srli_epi32::<5>(c0), m6)),
                    _mm512_and_si512(_mm512_srli_epi32::<5>(c1), m6),
                );
                let kg = _mm512_mask_or_epi32(kg, mode, kg, mode_g);
                let kb = _mm512_or_si512(
                    _mm512_slli_epi32::<5>(_mm512_and_si512(c0, m5)),
                    _mm512_and_si512(c1, m5),
                );
                let kb = _mm512_mask_or_epi32(kb, mode, kb, mode_rb);
                // Even lanes: red, blue; odd lanes: green (moved up one
                // lane), the indices as loaded.
                let rg = _mm512_mask_blend_epi32(
                    0xaaaa,
                    _mm512_slli_epi32::<4>(kr),
                    _mm512_slli_epi64::<32>(_mm512_slli_epi32::<4>(kg)),
                );
                let bi = _mm512_mask_blend_epi32(0xaaaa, _mm512_slli_epi32::<4>(kb), w);
                _mm512_storeu_si512(out[0].as_mut_ptr() as *mut __m512i, rg);
                _mm512_storeu_si512(out[1].as_mut_ptr() as *mut __m512i, bi);
            } else {
                for k in 0..BH {
                    let word = (col.add(8 * k) as *const u64).read_unaligned();
                    let [r, g, b, idx] = bc1_keys(word);
                    out[0][2 * k] = r << 4;
                    out[0][2 * k + 1] = g << 4;
                    out[1][2 * k] = b << 4;
                    out[1][2 * k + 1] = idx;
                }
            }
        }
        for (ci, &(_, c0)) in seg.iter().enumerate() {
            let bp = b0p.get_unchecked(c0 as usize / 4).as_ptr() as *const f32;
            // No closures here: intrinsics inside one may not be inlined
            // into this AVX-512 function.
            let b = [
                _mm512_broadcast_f32x4(_mm_loadu_ps(bp)),
                _mm512_broadcast_f32x4(_mm_loadu_ps(bp.add(4))),
                _mm512_broadcast_f32x4(_mm_loadu_ps(bp.add(8))),
            ];
            let key = &keys[ci];
            for (k, row) in a.iter_mut().enumerate() {
                let (kr, kg) = (key[0][2 * k] as usize, key[0][2 * k + 1] as usize);
                let (kb, idx) = (key[1][2 * k] as usize, key[1][2 * k + 1]);
                let iv = _mm512_srlv_epi32(_mm512_set1_epi32(idx as i32), shifts);
                let pr = _mm512_broadcast_f32x4(_mm_loadu_ps(t0.add(kr) as *const f32));
                let pg = _mm512_broadcast_f32x4(_mm_loadu_ps(t1.add(kg) as *const f32));
                let pb = _mm512_broadcast_f32x4(_mm_loadu_ps(t2.add(kb) as *const f32));
                row[0] = _mm512_fmadd_ps(_mm512_permutexvar_ps(iv, pr), b[0], row[0]);
                row[1] = _mm512_fmadd_ps(_mm512_permutexvar_ps(iv, pg), b[1], row[1]);
                row[2] = _mm512_fmadd_ps(_mm512_permutexvar_ps(iv, pb), b[2], row[2]);
            }
        }
    }
    for (k, row) in a.iter().enumerate() {
        for (c, v) in row.iter().enumerate() {
            _mm512_storeu_ps(acc[k][c].as_mut_ptr(), *v);
        }
    }
}

/// How many active block columns [`bc1_row_avx2`] takes through all its
/// block rows before moving on: 128 columns are 8 KiB of blocks, 16 KiB of
/// decoded keys and 6 KiB of `B0`, which stay in L1 while the 8 block rows
/// pass over them.
pub(super) const AVX2_SEGMENT: usize = 128;

/// A BC1 row of tiles on AVX2 + FMA: the [`bc1_row_avx512`] arithmetic in
/// 8-lane vectors, a block's 16 entries as two halves (its rows 0–1 and
/// 2–3). With 16 vector registers the accumulators of a whole row of tiles
/// do not fit, so the work goes by segments of [`AVX2_SEGMENT`] active
/// block columns:
/// - first the palette keys of every block of the segment are computed
///   eight blocks (one block column) at a time in vector registers and
///   stored by block row (the scalar key arithmetic was most of the
///   instructions per block);
/// - then per block row its 6 accumulators stay in registers while the
///   segment's columns pass: per block one index broadcast, two shifts,
///   three palette loads, six in-lane shuffles (`vpermilps`) and six fused
///   multiply-adds, with `B0` from [`super::columns::fill_b0_groups`].
///
/// The segment's blocks stay in L1 between block rows. (Before segments,
/// every block row passed over the whole row of tiles, whose blocks, `B0`
/// and palette tables overflow L2 at 16k patches.) The key pass prefetches
/// the column [`PREFETCH_AHEAD`] places on, as the AVX-512 path does. Per
/// accumulator lane the columns are added in the same order as on AVX-512,
/// whatever the segment length.
#[target_feature(enable = "avx2,fma")]
pub(super) unsafe fn bc1_row_avx2(
    dense: &[u8],
    cols: &[(u32, u32)],
    b0p: &[[[f32; 4]; 3]],
    tables: &[Bc1Table; 3],
    keys: &mut Vec<u32>,
    acc: &mut [[[f32; 16]; 3]],
) {
    use std::arch::x86_64::*;
    let bh = acc.len();
    let shifts_lo = _mm256_setr_epi32(0, 2, 4, 6, 8, 10, 12, 14);
    let shifts_hi = _mm256_setr_epi32(16, 18, 20, 22, 24, 26, 28, 30);
    let (t0, t1, t2) = (
        tables[0].values.as_ptr() as *const u8,
        tables[1].values.as_ptr() as *const u8,
        tables[2].values.as_ptr() as *const u8,
    );
    // keys[k * stride + ci]: block row k of the segment's column ci (sized
    // to the columns there are: few where most are skipped).
    let stride = AVX2_SEGMENT.min(cols.len());
    // Raw storage (the caller's buffer, kept between rows): every key is
    // written by the key pass before the block rows read it, through `kp`
    // only; the vector's length stays 0 and it never reads the memory
    // itself.
    keys.clear();
    keys.reserve(4 * bh * stride);
    let kp = keys.as_mut_ptr();
    // Per column of the segment: its group's entry in `b0p`.
    let mut groups = [0usize; AVX2_SEGMENT];
    // Vector key arithmetic (bc1_keys, eight blocks at once).
    let even = _mm256_setr_epi32(0, 2, 4, 6, 1, 3, 5, 7);
    let lo16 = _mm256_set1_epi32(0xffff);
    let (m5, m6) = (_mm256_set1_epi32(31), _mm256_set1_epi32(63));
    let (mode_rb, mode_g) = (_mm256_set1_epi32(1 << 10), _mm256_set1_epi32(1 << 12));
    // No closures below: intrinsics inside a closure may not be inlined
    // into this AVX2 function.
    for (si, seg) in cols.chunks(AVX2_SEGMENT).enumerate() {
        for (ci, &(off, c0)) in seg.iter().enumerate() {
            groups[ci] = c0 as usize / 4;
            // A hint (no effect on results).
            if let Some(&(next, _)) = cols.get(si * AVX2_SEGMENT + ci + PREFETCH_AHEAD) {
                _mm_prefetch::<_MM_HINT_T0>(dense.as_ptr().add(next as usize) as *const i8);
            }
            let col = dense.as_ptr().add(off as usize);
            if bh == 8 {
                // Blocks 0–3 and 4–7: endpoints in the low dword of each
                // 8-byte block, indices in the high one.
                let a =
                    _mm256_permutevar8x32_epi32(_mm256_loadu_si256(col as *const __m256i), even);
                let b = _mm256_permutevar8x32_epi32(
                    _mm256_loadu_si256(col.add(32) as *const __m256i),
                    even,
                );
                let ends = _mm256_permute2x128_si256::<0x20>(a, b);
                let idx = _mm256_permute2x128_si256::<0x31>(a, b);
                let c0 = _mm256_and_si256(ends, lo16);
                let c1 = _mm256_srli_epi32::<16>(ends);
                let mode = _mm256_cmpgt_epi32(c0, c1);
                let kr = _mm256_or_si256(
                    _mm256_or_si256(
                        _mm256_slli_epi32::<5>(_mm256_srli_epi32::<11>(c0)),
                        _mm256_srli_epi32::<11>(c1),
                    ),
                    _mm256_and_si256(mode, mode_rb),
                );
                let kg = _mm256_or_si256(
                    _mm256_or_si256(
                        _mm256_slli_epi32::<6>(_mm256_and_si256(_mm256_srli_epi32::<5>(c0), m6)),
                        _mm256_and_si256(_mm256_srli_epi32::<5>(c1), m6),
                    ),
                    _mm256_and_si256(mode, mode_g),
                );
                let kb = _mm256_or_si256(
                    _mm256_or_si256(
                        _mm256_slli_epi32::<5>(_mm256_and_si256(c0, m5)),
                        _mm256_and_si256(c1, m5),
                    ),
                    _mm256_and_si256(mode, mode_rb),
                );
                let (kr, kg, kb) = (
                    _mm256_slli_epi32::<4>(kr),
                    _mm256_slli_epi32::<4>(kg),
                    _mm256_slli_epi32::<4>(kb),
                );
                // Transpose to one [kr, kg, kb, idx] per block.
                let rg_lo = _mm256_unpacklo_epi32(kr, kg);
                let rg_hi = _mm256_unpackhi_epi32(kr, kg);
                let bi_lo = _mm256_unpacklo_epi32(kb, idx);
                let bi_hi = _mm256_unpackhi_epi32(kb, idx);
                let q0 = _mm256_unpacklo_epi64(rg_lo, bi_lo); // blocks 0, 4
                let q1 = _mm256_unpackhi_epi64(rg_lo, bi_lo); // blocks 1, 5
                let q2 = _mm256_unpacklo_epi64(rg_hi, bi_hi); // blocks 2, 6
                let q3 = _mm256_unpackhi_epi64(rg_hi, bi_hi); // blocks 3, 7
                for (k, q) in [(0, q0), (1, q1), (2, q2), (3, q3)] {
                    let p0 = kp.add(4 * (k * stride + ci)) as *mut __m128i;
                    let p4 = kp.add(4 * ((k + 4) * stride + ci)) as *mut __m128i;
                    _mm_storeu_si128(p0, _mm256_castsi256_si128(q));
                    _mm_storeu_si128(p4, _mm256_extracti128_si256::<1>(q));
                }
            } else {
                for k in 0..bh {
                    let word = (col.add(8 * k) as *const u64).read_unaligned();
                    let [r, g, b, idx] = bc1_keys(word);
                    let key = kp.add(4 * (k * stride + ci));
                    for (l, v) in [r << 4, g << 4, b << 4, idx].into_iter().enumerate() {
                        *key.add(l) = v;
                    }
                }
            }
        }
        for (k, a) in acc.iter_mut().enumerate() {
            let (mut lr, mut lg, mut lb) = (
                _mm256_loadu_ps(a[0].as_ptr()),
                _mm256_loadu_ps(a[1].as_ptr()),
                _mm256_loadu_ps(a[2].as_ptr()),
            );
            let (mut hr, mut hg, mut hb) = (
                _mm256_loadu_ps(a[0].as_ptr().add(8)),
                _mm256_loadu_ps(a[1].as_ptr().add(8)),
                _mm256_loadu_ps(a[2].as_ptr().add(8)),
            );
            let row = kp.add(4 * k * stride);
            for (ci, &g) in groups[..seg.len()].iter().enumerate() {
                let key = row.add(4 * ci);
                // Unaligned loads, each broadcast to both halves: the
                // buffers are only f32-aligned (a reference to an __m128
                // there would claim 16 bytes).
                // (A macro, not a closure: intrinsics in a closure may not
                // be inlined into this AVX2 function.)
                macro_rules! both {
                    ($p:expr) => {{
                        let x = _mm_loadu_ps($p);
                        _mm256_set_m128(x, x)
                    }};
                }
                let b = b0p.get_unchecked(g).as_ptr() as *const f32;
                let (br, bg, bb) = (both!(b), both!(b.add(4)), both!(b.add(8)));
                let idx = _mm256_set1_epi32(*key.add(3) as i32);
                // vpermilps picks within each 128-bit half by the low two
                // bits of each lane, so the shifted indices need no mask
                // and the palette (in both halves) costs one cheap shuffle.
                let ilo = _mm256_srlv_epi32(idx, shifts_lo);
                let ihi = _mm256_srlv_epi32(idx, shifts_hi);
                let pr = both!(t0.add(*key as usize) as *const f32);
                let pg = both!(t1.add(*key.add(1) as usize) as *const f32);
                let pb = both!(t2.add(*key.add(2) as usize) as *const f32);
                lr = _mm256_fmadd_ps(_mm256_permutevar_ps(pr, ilo), br, lr);
                hr = _mm256_fmadd_ps(_mm256_permutevar_ps(pr, ihi), br, hr);
                lg = _mm256_fmadd_ps(_mm256_permutevar_ps(pg, ilo), bg, lg);
                hg = _mm256_fmadd_ps(_mm256_permutevar_ps(pg, ihi), bg, hg);
                lb = _mm256_fmadd_ps(_mm256_permutevar_ps(pb, ilo), bb, lb);
                hb = _mm256_fmadd_ps(_mm256_permutevar_ps(pb, ihi), bb, hb);
            }
            _mm256_storeu_ps(a[0].as_mut_ptr(), lr);
            _mm256_storeu_ps(a[0].as_mut_ptr().add(8), hr);
            _mm256_storeu_ps(a[1].as_mut_ptr(), lg);
            _mm256_storeu_ps(a[1].as_mut_ptr().add(8), hg);
            _mm256_storeu_ps(a[2].as_mut_ptr(), lb);
            _mm256_storeu_ps(a[2].as_mut_ptr().add(8), hb);
        }
    }
}

/// A BC4 block's 16 values (lane `l`: `pal[(bits >> 3l) & 7]`, `bits`
/// the 48 index bits) by one `vpermps` from the palette held twice in a
/// vector, instead of the 16-lane gather from memory the compiler makes
/// of the portable selection (whose latency each block waited for). The
/// same values, so the same products and bits.
#[target_feature(enable = "avx512f")]
#[inline]
pub(super) unsafe fn bc4_values_avx512(pal: &[f32; 8], bits: u64) -> [f32; 16] {
    use std::arch::x86_64::*;
    let mut out = [0.0f32; 16];
    _mm512_storeu_ps(out.as_mut_ptr(), bc4_select_avx512(pal.as_ptr(), bits));
    out
}

/// The selection of [`bc4_values_avx512`] in a register: the 8 levels at
/// `pal`, the 48 index bits in `bits`.
#[target_feature(enable = "avx512f")]
#[inline]
unsafe fn bc4_select_avx512(pal: *const f32, bits: u64) -> std::arch::x86_64::__m512 {
    use std::arch::x86_64::*;
    let p = _mm512_castps256_ps512(_mm256_loadu_ps(pal));
    // 128-bit chunks 0, 1, 0, 1: entry j at lanes j and j + 8, so the
    // permute's fourth index bit (the next entry's lowest) picks an equal
    // copy and needs no mask.
    let p = _mm512_shuffle_f32x4::<0b01_00_01_00>(p, p);
    let q = _mm512_set1_epi64(bits as i64);
    let lo = _mm512_srlv_epi64(q, _mm512_setr_epi64(0, 3, 6, 9, 12, 15, 18, 21));
    let hi = _mm512_srlv_epi64(q, _mm512_setr_epi64(24, 27, 30, 33, 36, 39, 42, 45));
    let idx = _mm512_inserti64x4::<1>(
        _mm512_castsi256_si512(_mm512_cvtepi64_epi32(lo)),
        _mm512_cvtepi64_epi32(hi),
    );
    _mm512_permutexvar_ps(idx, p)
}

/// A grey (one-channel) BC4 row of tiles of `BH` block rows gathering `CH`
/// channels of `B0` (3, or 1 when `B0` is grey too) on AVX-512, laid out
/// as [`bc1_row_avx512`]'s (`cols`: active block columns, byte offset and
/// first column; `b0p` from [`super::columns::fill_b0_groups`]) with the `CH BH`
/// accumulators in registers for the whole row. Per block: its palette, one load from the
/// table of every endpoint pair (`pairs`, [`super::palette::bc4_palette`]), its 16
/// values picked as [`bc4_values_avx512`] picks them, and per channel one
/// multiply and one add (not fused: the portable path's `acc += v · b`,
/// so the same bits). The palettes of the blocks `PAIR_AHEAD` columns on
/// are prefetched (the table is 2 MiB, beyond L1 and L2 for random pairs).
#[target_feature(enable = "avx512f")]
pub(super) unsafe fn bc4_grey_row_avx512<const BH: usize, const CH: usize>(
    dense: &[u8],
    cols: &[(u32, u32)],
    b0p: &[[[f32; 4]; 3]],
    pairs: &[[f32; 8]],
    acc: &mut [[[f32; 16]; 3]],
) {
    use std::arch::x86_64::*;
    const PAIR_AHEAD: usize = 4;
    let pair = |w: u64| ((w & 0xff) << 8 | ((w >> 8) & 0xff)) as usize;
    let mut a = [[_mm512_setzero_ps(); CH]; BH];
    for (k, row) in a.iter_mut().enumerate() {
        for (c, v) in row.iter_mut().enumerate() {
            *v = _mm512_loadu_ps(acc[k][c].as_ptr());
        }
    }
    for (ci, &(off, c0)) in cols.iter().enumerate() {
        if let Some(&(next, _)) = cols.get(ci + PAIR_AHEAD) {
            let col = dense.as_ptr().add(next as usize);
            for k in 0..BH {
                let w = (col.add(8 * k) as *const u64).read_unaligned();
                _mm_prefetch::<_MM_HINT_T0>(pairs.as_ptr().add(pair(w)) as *const i8);
            }
        }
        let bp = b0p.get_unchecked(c0 as usize / 4).as_ptr() as *const f32;
        let mut b = [_mm512_setzero_ps(); CH];
        for (c, bc) in b.iter_mut().enumerate() {
            *bc = _mm512_broadcast_f32x4(_mm_loadu_ps(bp.add(4 * c)));
        }
        let col = dense.as_ptr().add(off as usize);
        for (k, row) in a.iter_mut().enumerate() {
            let w = (col.add(8 * k) as *const u64).read_unaligned();
            let v = bc4_select_avx512(pairs.get_unchecked(pair(w)).as_ptr(), w >> 16);
            for (r, bc) in row.iter_mut().zip(&b) {
                *r = _mm512_add_ps(*r, _mm512_mul_ps(v, *bc));
            }
        }
    }
    for (k, row) in a.iter().enumerate() {
        for (c, v) in row.iter().enumerate() {
            _mm512_storeu_ps(acc[k][c].as_mut_ptr(), *v);
        }
    }
}
