//! The gather `H = T̃ · B0` straight from the compressed matrix (DESIGN.md
//! run time step 3), on the CPU: decode fused with the multiply-add, no
//! decoded matrix in memory, multithreaded over rows of tiles, vectorised
//! (AVX-512 where the CPU has it, a portable path otherwise, which is also
//! its reference in the tests).
//!
//! **What is skipped.** Tiles that are zero in every channel are not stored
//! (the codec). Columns of `B0` that are zero in every channel, in groups
//! of 4 (one BC block column): at load the stored tiles are re-laid so that
//! each block column of a tile is contiguous (64 bytes for a BC1 tile, one
//! cache line), so a skipped group skips memory, not just arithmetic; a
//! tile whose 8 block columns are all inactive is not touched at all.
//! Sparse entries of inactive columns are not multiplied. A grey matrix
//! (one stored channel) is decoded once for the three channels of `B0`;
//! when `B0`'s channels are equal too, one product serves all three.
//! Skipping changes no bit of the result: a skipped term is `v · 0`, and
//! `a + 0 = a` exactly, while the remaining terms are added in the same
//! order.
//!
//! **Decoding.** BC1: the palette of a block depends per channel only on
//! that channel's two endpoint values and the block's mode, so at load a
//! table of every (endpoint, endpoint, mode) → four decoded values per
//! channel is built (5-bit channels: 2 × 32² entries, 6-bit: 2 × 64²;
//! 192 KiB in all, resident in L2); the decoded value of each palette entry
//! is `bcdec_rs`'s rounding of the interpolated byte, through the codec's
//! log table, exactly as [`Encoded::decode`]. A block then costs three
//! table reads, and per channel one permute of its 16 two-bit indices and
//! one fused multiply-add. BC4: the 8 levels of a block are looked up in a
//! table indexed by the interpolation's numerator. BC6H, f16 and f32 are
//! decoded a tile at a time into a buffer by the codec's own decoder and
//! multiplied (the same skipping by tiles and column groups, arithmetic
//! only inside a tile).

use crate::bakefile::codec::decode::{decode_tile_bytes, Codebook};
use crate::bakefile::codec::rgb9e5;
use crate::bakefile::codec::{DenseFormat, Encoded, SparseValues};
use rayon::prelude::*;

/// Column groups of `B0` that take part in a product: group `g` covers
/// columns `4g..4g + 4`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ActiveColumns {
    /// Per group of 4 columns: some channel of `B0` is non-zero there.
    pub group: Vec<bool>,
    /// Per tile column: some group in it is active.
    pub tile: Vec<bool>,
    /// Groups active, for reports.
    pub active_groups: usize,
}

impl ActiveColumns {
    /// The active groups of `b0` (every column when `all`).
    pub fn of(b0: [&[f32]; 3], tile: usize, all: bool) -> ActiveColumns {
        let n = b0[0].len();
        let groups = n.div_ceil(4);
        let group: Vec<bool> = (0..groups)
            .map(|g| all || (4 * g..(4 * g + 4).min(n)).any(|j| b0.iter().any(|c| c[j] != 0.0)))
            .collect();
        let per_tile = tile / 4;
        let tile_flags = group
            .chunks(per_tile.max(1))
            .map(|c| c.iter().any(|&a| a))
            .collect();
        ActiveColumns {
            active_groups: group.iter().filter(|&&a| a).count(),
            group,
            tile: tile_flags,
        }
    }
}

/// What one product read and did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GatherStats {
    /// Bytes of compressed matrix read: dense block columns touched, the
    /// tile index, and the sparse part's entries of active columns' rows.
    pub bytes_read: u64,
    /// Stored tiles touched, and skipped because all their columns were
    /// inactive.
    pub tiles_touched: u64,
    pub tiles_skipped: u64,
    /// Matrix entries decoded and multiplied (per stored channel).
    pub entries: u64,
}

/// The BC1 palette tables of one channel (module doc).
struct Bc1Table {
    /// `[mode][e0 << bits | e1]` → 4 decoded values.
    values: Vec<[f32; 4]>,
    bits: u32,
}

/// The sparse part as the gather reads it.
struct SparseRt {
    row_ptr: Vec<u32>,
    cols: Vec<u32>,
    /// RGB9E5 words (precision RGB9E5) or values (`channels` per entry).
    packed: Vec<u32>,
    values: Vec<f32>,
    /// RGB9E5: `2^(e − 24) / scale_c` per exponent and channel.
    exp_factor: [[f32; 3]; 32],
    channels: usize,
    rgb9e5: bool,
}

/// A compressed matrix laid out for the CPU gather.
pub struct CompressedGather {
    n: usize,
    image: usize,
    tile: usize,
    tiles_per_side: usize,
    format: DenseFormat,
    channels: usize,
    /// Stored tiles, each re-laid block column by block column (BC1, BC4)
    /// or as in the file (other formats).
    dense: Vec<u8>,
    row_start: Vec<u32>,
    cols: Vec<u16>,
    offsets: Vec<u32>,
    bc1: Option<[Bc1Table; 3]>,
    /// BC4: value of numerator `k` of the 8-level (`/7`) and 6-level (`/5`)
    /// interpolations, per channel.
    bc4_7: Vec<[f32; 1786]>,
    bc4_5: Vec<[f32; 1276]>,
    book: Codebook,
    sparse: SparseRt,
    bytes_index: u64,
    simd: bool,
}

fn expand5(v: u32) -> u32 {
    (v * 527 + 23) >> 6
}

fn expand6(v: u32) -> u32 {
    (v * 259 + 33) >> 6
}

/// `bcdec_rs`'s BC1 palette of one channel: endpoints `a`, `b` (5 or 6
/// bits), 4-colour mode or not.
fn bc1_palette_bytes(a: u32, b: u32, six: bool, four: bool) -> [u8; 4] {
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

impl CompressedGather {
    /// Lays `e` out for the gather; `simd` allows the AVX-512 path when the
    /// CPU has it (off: the portable path).
    pub fn new(e: &Encoded, simd: bool) -> CompressedGather {
        let book = e.codebook();
        let tile = e.index.tile;
        let tps = e.index.tiles_per_side;
        let block_bytes = match e.format {
            DenseFormat::Bc1 => 8,
            DenseFormat::Bc4 => 8 * e.channels,
            _ => 0,
        };
        let mut dense = Vec::with_capacity(e.dense.len());
        let mut offsets = Vec::with_capacity(e.index.offsets.len());
        for tr in 0..tps {
            let h = tile.min(e.image_size - tr * tile);
            for slot in e.index.row_start[tr] as usize..e.index.row_start[tr + 1] as usize {
                let w = tile.min(e.image_size - e.index.cols[slot] as usize * tile);
                let start = e.index.offsets[slot] as usize;
                let len = e.format.tile_bytes(h, w, e.channels);
                let src = &e.dense[start..start + len];
                offsets.push(dense.len() as u32);
                if block_bytes == 0 {
                    dense.extend_from_slice(src);
                    continue;
                }
                let (bh, bw) = (h / 4, w / 4);
                for bc in 0..bw {
                    for br in 0..bh {
                        let k = br * bw + bc;
                        if e.format == DenseFormat::Bc1 {
                            dense.extend_from_slice(&src[8 * k..8 * k + 8]);
                        } else {
                            // BC4 planes: channel c's block k at c·plane + 8k.
                            let plane = bh * bw * 8;
                            for c in 0..e.channels {
                                dense.extend_from_slice(
                                    &src[c * plane + 8 * k..c * plane + 8 * k + 8],
                                );
                            }
                        }
                    }
                }
            }
        }
        let bc1 = (e.format == DenseFormat::Bc1).then(|| {
            std::array::from_fn(|c| {
                let six = c == 1;
                let bits = if six { 6 } else { 5 };
                let size = 1usize << (2 * bits);
                let mut values = vec![[0.0f32; 4]; 2 * size];
                for mode in 0..2 {
                    for a in 0..1u32 << bits {
                        for b in 0..1u32 << bits {
                            let bytes = bc1_palette_bytes(a, b, six, mode == 1);
                            values[mode * size + ((a << bits) | b) as usize] =
                                bytes.map(|q| book.lut[c][q as usize]);
                        }
                    }
                }
                Bc1Table { values, bits }
            })
        });
        let (mut bc4_7, mut bc4_5) = (Vec::new(), Vec::new());
        if e.format == DenseFormat::Bc4 {
            for c in 0..e.channels {
                let value = |x: f32| {
                    if x <= 0.0 {
                        0.0
                    } else {
                        e.scale[c] * (e.log_range * (x - 1.0)).exp()
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
                bc4_7.push(t7);
                bc4_5.push(t5);
            }
        }
        let sp = &e.sparse;
        let rgb9e5 = sp.precision == SparseValues::Rgb9e5 && !sp.is_empty();
        let mut exp_factor = [[0.0f32; 3]; 32];
        for (ex, f) in exp_factor.iter_mut().enumerate() {
            for (fc, s) in f.iter_mut().zip(sp.scale) {
                *fc = (2f64.powi(ex as i32 - 24) / s as f64) as f32;
            }
        }
        let sparse = SparseRt {
            row_ptr: sp.row_ptr.clone(),
            cols: sp.cols.clone(),
            packed: if rgb9e5 {
                sp.values
                    .chunks_exact(3)
                    .map(|v| rgb9e5::pack(std::array::from_fn(|c| v[c] * sp.scale[c])))
                    .collect()
            } else {
                Vec::new()
            },
            values: if rgb9e5 {
                Vec::new()
            } else {
                sp.values.clone()
            },
            exp_factor,
            channels: e.channels,
            rgb9e5,
        };
        CompressedGather {
            n: e.n,
            image: e.image_size,
            tile,
            tiles_per_side: tps,
            format: e.format,
            channels: e.channels,
            dense,
            row_start: e.index.row_start.clone(),
            cols: e.index.cols.clone(),
            offsets,
            bc1,
            bc4_7,
            bc4_5,
            book,
            sparse,
            bytes_index: e.bytes_index() as u64,
            simd: simd && simd_available(),
        }
    }

    /// Whether the vectorised path runs.
    pub fn simd(&self) -> bool {
        self.simd
    }

    /// Matrix size.
    pub fn n(&self) -> usize {
        self.n
    }

    /// Stored channels (1 for a grey matrix).
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// `H = T̃ · B0` over the `active` column groups, written to `h` (three
    /// channels, `n` each). `b0`'s channels may alias (a grey `B0`).
    pub fn gather(
        &self,
        b0: [&[f32]; 3],
        active: &ActiveColumns,
        h: &mut [Vec<f32>; 3],
    ) -> GatherStats {
        let n = self.n;
        let grey_b0 = b0[0] == b0[1] && b0[1] == b0[2];
        // Channels of B0 to multiply: one when both the matrix and B0 are grey.
        let out_ch = if self.channels == 1 && grey_b0 { 1 } else { 3 };
        let tile = self.tile;
        let results: Vec<(Vec<[f32; 3]>, GatherStats)> = (0..self.tiles_per_side)
            .into_par_iter()
            .map(|tr| self.tile_row(tr, b0, active, out_ch))
            .collect();
        let mut stats = GatherStats {
            bytes_read: self.bytes_index,
            ..Default::default()
        };
        for (tr, (rows, s)) in results.into_iter().enumerate() {
            stats.bytes_read += s.bytes_read;
            stats.tiles_touched += s.tiles_touched;
            stats.tiles_skipped += s.tiles_skipped;
            stats.entries += s.entries;
            for (r, v) in rows.iter().enumerate() {
                let i = tr * tile + r;
                if i < n {
                    for c in 0..3 {
                        h[c][i] = v[c.min(out_ch - 1)];
                    }
                }
            }
        }
        stats
    }

    /// One row of tiles: its rows of `H` (dense, then sparse).
    fn tile_row(
        &self,
        tr: usize,
        b0: [&[f32]; 3],
        active: &ActiveColumns,
        out_ch: usize,
    ) -> (Vec<[f32; 3]>, GatherStats) {
        let tile = self.tile;
        let h = tile.min(self.image - tr * tile);
        let mut stats = GatherStats::default();
        let mut rows = vec![[0.0f32; 3]; h];
        match self.format {
            DenseFormat::Bc1 | DenseFormat::Bc4 => {
                // Per block row and output channel: 16 lanes (row r, column
                // c of the block at lane 4r + c).
                let bh = h / 4;
                let mut acc = vec![[[0.0f32; 16]; 3]; bh];
                for slot in self.row_start[tr] as usize..self.row_start[tr + 1] as usize {
                    let tc = self.cols[slot] as usize;
                    if !active.tile[tc] {
                        stats.tiles_skipped += 1;
                        continue;
                    }
                    stats.tiles_touched += 1;
                    let w = tile.min(self.image - tc * tile);
                    let bw = w / 4;
                    let block_bytes = if self.format == DenseFormat::Bc1 {
                        8
                    } else {
                        8 * self.channels
                    };
                    let col_bytes = bh * block_bytes;
                    let base = self.offsets[slot] as usize;
                    for bc in 0..bw {
                        let g = tc * tile / 4 + bc;
                        if !active.group[g] {
                            continue;
                        }
                        let c0 = 4 * g;
                        let mut b = [[0.0f32; 4]; 3];
                        for (ch, bch) in b.iter_mut().enumerate().take(out_ch) {
                            for (k, v) in bch.iter_mut().enumerate() {
                                *v = b0[ch].get(c0 + k).copied().unwrap_or(0.0);
                            }
                        }
                        let col = &self.dense[base + bc * col_bytes..base + (bc + 1) * col_bytes];
                        stats.bytes_read += col_bytes as u64;
                        stats.entries += (16 * bh * self.channels) as u64;
                        if self.format == DenseFormat::Bc1 {
                            self.bc1_column(col, &b, &mut acc);
                        } else {
                            self.bc4_column(col, &b, out_ch, &mut acc);
                        }
                    }
                }
                for (br, a) in acc.iter().enumerate() {
                    for r in 0..4 {
                        for ch in 0..out_ch {
                            let l = &a[ch][4 * r..4 * r + 4];
                            rows[4 * br + r][ch] = (l[0] + l[1]) + (l[2] + l[3]);
                        }
                    }
                }
            }
            _ => {
                let mut buf = vec![0.0f32; tile * tile * self.channels];
                let ch = self.channels;
                for slot in self.row_start[tr] as usize..self.row_start[tr + 1] as usize {
                    let tc = self.cols[slot] as usize;
                    if !active.tile[tc] {
                        stats.tiles_skipped += 1;
                        continue;
                    }
                    stats.tiles_touched += 1;
                    let w = tile.min(self.image - tc * tile);
                    let len = self.format.tile_bytes(h, w, ch);
                    let start = self.offsets[slot] as usize;
                    decode_tile_bytes(&self.book, &self.dense[start..start + len], h, w, &mut buf);
                    stats.bytes_read += len as u64;
                    stats.entries += (h * w * ch) as u64;
                    let c0 = tc * tile;
                    for (r, row) in rows.iter_mut().enumerate() {
                        for c in 0..w {
                            let j = c0 + c;
                            if j >= self.n || !active.group[j / 4] {
                                continue;
                            }
                            let v = &buf[(r * w + c) * ch..(r * w + c + 1) * ch];
                            for (oc, o) in row.iter_mut().enumerate().take(out_ch) {
                                *o += v[oc.min(ch - 1)] * b0[oc][j];
                            }
                        }
                    }
                }
            }
        }
        // The sparse part of these rows.
        let sp = &self.sparse;
        if !sp.row_ptr.is_empty() {
            for (r, row) in rows.iter_mut().enumerate() {
                let i = tr * tile + r;
                if i >= self.n {
                    break;
                }
                let (a, b) = (sp.row_ptr[i] as usize, sp.row_ptr[i + 1] as usize);
                stats.bytes_read +=
                    4 * (b - a) as u64 * if sp.rgb9e5 { 2 } else { 1 + sp.channels as u64 };
                for e in a..b {
                    let j = sp.cols[e] as usize;
                    if !active.group[j / 4] {
                        continue;
                    }
                    let v: [f32; 3] = if sp.rgb9e5 {
                        let p = sp.packed[e];
                        let f = &sp.exp_factor[(p >> 27) as usize];
                        [
                            (p & 0x1ff) as f32 * f[0],
                            ((p >> 9) & 0x1ff) as f32 * f[1],
                            ((p >> 18) & 0x1ff) as f32 * f[2],
                        ]
                    } else {
                        let s = &sp.values[e * sp.channels..(e + 1) * sp.channels];
                        std::array::from_fn(|c| s[c.min(sp.channels - 1)])
                    };
                    for (oc, o) in row.iter_mut().enumerate().take(out_ch) {
                        *o += v[oc] * b0[oc][j];
                    }
                }
            }
        }
        (rows, stats)
    }

    /// One BC1 block column (`bh` blocks) times `b`, into `acc`.
    fn bc1_column(&self, col: &[u8], b: &[[f32; 4]; 3], acc: &mut [[[f32; 16]; 3]]) {
        let tables = self.bc1.as_ref().expect("BC1 tables");
        #[cfg(target_arch = "x86_64")]
        if self.simd {
            // SAFETY: `simd` is set only when the CPU reports AVX-512F.
            unsafe { bc1_column_avx512(col, b, tables, acc) };
            return;
        }
        for (k, a) in acc.iter_mut().enumerate() {
            let blk = &col[8 * k..8 * k + 8];
            let c0 = u16::from_le_bytes([blk[0], blk[1]]) as u32;
            let c1 = u16::from_le_bytes([blk[2], blk[3]]) as u32;
            let idx = u32::from_le_bytes([blk[4], blk[5], blk[6], blk[7]]);
            let mode = usize::from(c0 > c1);
            let keys = [
                ((c0 >> 11) << 5) | (c1 >> 11),
                (((c0 >> 5) & 63) << 6) | ((c1 >> 5) & 63),
                ((c0 & 31) << 5) | (c1 & 31),
            ];
            for ch in 0..3 {
                let t = &tables[ch];
                let pal = &t.values[(mode << (2 * t.bits)) + keys[ch] as usize];
                for (lane, v) in a[ch].iter_mut().enumerate() {
                    let q = (idx >> (2 * lane)) & 3;
                    *v += pal[q as usize] * b[ch][lane & 3];
                }
            }
        }
    }

    /// One BC4 block column (`bh` blocks of `channels` channels) times `b`.
    fn bc4_column(&self, col: &[u8], b: &[[f32; 4]; 3], out_ch: usize, acc: &mut [[[f32; 16]; 3]]) {
        let chs = self.channels;
        for (k, a) in acc.iter_mut().enumerate() {
            for c in 0..chs {
                let blk = &col[8 * (k * chs + c)..8 * (k * chs + c) + 8];
                let (r0, r1) = (blk[0] as usize, blk[1] as usize);
                let mut pal = [0.0f32; 8];
                if r0 > r1 {
                    let t = &self.bc4_7[c];
                    pal[0] = t[7 * r0];
                    pal[1] = t[7 * r1];
                    for (i, p) in pal.iter_mut().enumerate().skip(2) {
                        *p = t[(8 - i) * r0 + (i - 1) * r1];
                    }
                } else {
                    let t = &self.bc4_5[c];
                    pal[0] = t[5 * r0];
                    pal[1] = t[5 * r1];
                    for (i, p) in pal.iter_mut().enumerate().take(6).skip(2) {
                        *p = t[(6 - i) * r0 + (i - 1) * r1];
                    }
                    pal[6] = 0.0;
                    pal[7] = t[5 * 255];
                }
                let bits = u64::from_le_bytes(blk.try_into().unwrap()) >> 16;
                // One stored channel serves every output channel.
                let outs: &[usize] = if chs == 1 {
                    &[0, 1, 2][..out_ch]
                } else {
                    &[0, 1, 2][c..c + 1]
                };
                for &oc in outs {
                    for (lane, v) in a[oc].iter_mut().enumerate() {
                        let q = (bits >> (3 * lane)) & 7;
                        *v += pal[q as usize] * b[oc][lane & 3];
                    }
                }
            }
        }
    }
}

/// Whether this CPU runs the AVX-512 path.
pub fn simd_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx512f")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// [`CompressedGather::bc1_column`] with AVX-512: per block, the 16 indices
/// in one vector, and per channel one permute of the 4-entry palette and
/// one fused multiply-add into the block row's 16-lane accumulator.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn bc1_column_avx512(
    col: &[u8],
    b: &[[f32; 4]; 3],
    tables: &[Bc1Table; 3],
    acc: &mut [[[f32; 16]; 3]],
) {
    use std::arch::x86_64::*;
    let shifts = _mm512_setr_epi32(0, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 22, 24, 26, 28, 30);
    let three = _mm512_set1_epi32(3);
    let bv: [__m512; 3] =
        std::array::from_fn(|c| _mm512_broadcast_f32x4(_mm_loadu_ps(b[c].as_ptr())));
    for (k, a) in acc.iter_mut().enumerate() {
        let blk = &col[8 * k..8 * k + 8];
        let c0 = u16::from_le_bytes([blk[0], blk[1]]) as u32;
        let c1 = u16::from_le_bytes([blk[2], blk[3]]) as u32;
        let idx = u32::from_le_bytes([blk[4], blk[5], blk[6], blk[7]]);
        let mode = usize::from(c0 > c1);
        let keys = [
            ((c0 >> 11) << 5) | (c1 >> 11),
            (((c0 >> 5) & 63) << 6) | ((c1 >> 5) & 63),
            ((c0 & 31) << 5) | (c1 & 31),
        ];
        let iv = _mm512_and_epi32(
            _mm512_srlv_epi32(_mm512_set1_epi32(idx as i32), shifts),
            three,
        );
        for ch in 0..3 {
            let t = &tables[ch];
            let pal = t
                .values
                .get_unchecked((mode << (2 * t.bits)) + keys[ch] as usize);
            let pv = _mm512_broadcast_f32x4(_mm_loadu_ps(pal.as_ptr()));
            let vals = _mm512_permutexvar_ps(iv, pv);
            let ap = a[ch].as_mut_ptr();
            _mm512_storeu_ps(ap, _mm512_fmadd_ps(vals, bv[ch], _mm512_loadu_ps(ap)));
        }
    }
}

/// `H = T · b` for a dense row-major f32 matrix per channel: the plain
/// product (for tests and the classic baseline's checks), f64 accumulation.
pub fn dense_product(t: [&[f32]; 3], n: usize, b0: [&[f32]; 3]) -> [Vec<f64>; 3] {
    std::array::from_fn(|c| {
        (0..n)
            .into_par_iter()
            .map(|i| {
                t[c][i * n..(i + 1) * n]
                    .iter()
                    .zip(b0[c])
                    .map(|(&a, &b)| a as f64 * b as f64)
                    .sum()
            })
            .collect()
    })
}
