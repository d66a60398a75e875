//! The gather `H = T̃ · B0` straight from the compressed matrix (docs/design.md
//! run time step 3), on the CPU: decode fused with the multiply-add, no
//! decoded matrix in memory, multithreaded over rows of tiles, vectorised
//! (AVX-512 where the CPU has it, else AVX2 with FMA, else a portable path,
//! which is also their reference in the tests).
//!
//! **What is skipped.** Tiles that are zero in every channel are not stored
//! (the codec). Columns of `B0` that are zero in every channel, in groups
//! of 4 (one BC block column): at load the stored tiles are re-laid so that
//! each block column of a tile is contiguous (64 bytes for a BC1 tile, one
//! cache line), so a skipped group skips memory, not just arithmetic; a
//! tile whose 8 block columns are all inactive is not touched at all.
//! The sparse part is re-laid at load by tile and, within a tile, by
//! group of 4 columns, with each group's start stored, so sparse entries
//! of inactive groups are not read either. A row of tiles finds its tiles
//! and sparse blocks in active tile columns through tables by (tile row,
//! tile column) (8 bytes per tile of the image, beside the codec's own 4),
//! and `B0` is re-laid for the kernels in the active groups only, so that
//! the work outside the kernels also follows the active columns (a product
//! with nothing active: 31–46 µs on Sponza at 3,965 patches, 55–57 µs when
//! every stored tile was tested). Active block columns scattered
//! by skipping are prefetched a few columns ahead (the hardware prefetcher
//! predicts only the contiguous case). A grey matrix
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
//! table indexed by the interpolation's numerator, and its 16 values are
//! picked from them once (on AVX-512 by one permute), then multiplied into
//! every channel of `B0` they serve, in code compiled for the CPU's widest
//! vectors. A grey matrix (one BC4 channel) gathering three channels runs
//! on AVX-512 as BC1 does, its accumulators in registers for a row of
//! tiles and a block's palette one load from a table of every endpoint
//! pair. BC6H, f16 and f32 are re-laid by block column too and
//! gathered in `float`: f16 and f32 at the memory's speed (one load,
//! conversion and multiply-add per 16 values), BC6H from blocks unpacked at
//! load (`bc6h`: its endpoints, weights and region mask, so that a frame
//! decodes each block in integer arithmetic that vectorises).

pub use bc6h::{unpack as unpack_bc6h_block, UNPACKED_BYTES as BC6H_UNPACKED_BYTES};
pub use palette::bc4_levels;
use palette::{bc1_keys, bc1_palette_bytes, bc4_palette, Bc1Table};
use radiosity_bakefile::codec::decode::Codebook;
use radiosity_bakefile::codec::{DenseFormat, Encoded};
use rayon::prelude::*;
pub use sparse::rgb9e5_factors;
use sparse::{fill_b0_columns, sparse_avx2_available, SparseRt};

mod bc6h;
mod float;
mod palette;
mod sparse;
#[cfg(target_arch = "x86_64")]
mod x86;

/// Column groups of `B0` that take part in a product: group `g` covers
/// columns `4g..4g + 4`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ActiveColumns {
    /// Per tile column: bit `l` set when its group `l` is active, that is
    /// some channel of `B0` is non-zero in its 4 columns (a tile has at
    /// most 64 groups: `MAX_TILE / 4`); a tile column is active when its
    /// mask is not 0. The gather walks the set bits instead of testing
    /// every group, whose pattern branch predictors miss.
    pub mask: Vec<u64>,
    /// Groups active, for reports.
    pub active_groups: usize,
    /// The active tile columns (mask not 0), ascending: a row of tiles
    /// visits these, not all its stored tiles, so that a gather with few
    /// active columns costs in proportion to them.
    pub tiles: Vec<u32>,
}

impl ActiveColumns {
    /// The active groups of `b0` (every column when `all`).
    pub fn of(b0: [&[f32]; 3], tile: usize, all: bool) -> ActiveColumns {
        let n = b0[0].len();
        let groups = n.div_ceil(4);
        let group: Vec<bool> = (0..groups).map(|g| all || group_lit(b0, g)).collect();
        ActiveColumns::from_groups(&group, tile)
    }

    /// The active groups of `b0` less its negligible ones: with `weights`
    /// the column sums of `T̃` per channel ([`Encoded::column_sums`]),
    /// group `g` carries at most `e_g = Σ_{j ∈ g} Σ_c s_cj |b0_cj|` of the
    /// product's L1 norm (`s` sums magnitudes). The groups are
    /// dropped from the smallest `e_g` up (ties by index, so the choice is
    /// deterministic) while the dropped `e_g` sum to at most `eps` times
    /// their total `E`, so `‖T̃ b0 − T̃ b0_kept‖₁ ≤ eps · E` (a bound on the
    /// product's part lost, before f32 rounding; `E ≥ ‖T̃ b0‖₁`, with
    /// equality when `T̃` and `b0` are ≥ 0, as they are but for the
    /// near-field correction's `δ`). Groups whose columns of `T̃` are all zero
    /// (`e_g = 0`) go for free. With `eps = 0`, exactly [`Self::of`]'s
    /// groups less those: the same product bit for bit (each dropped term
    /// is `0 · b`).
    pub fn culled(b0: [&[f32]; 3], tile: usize, weights: &[Vec<f64>; 3], eps: f64) -> Culled {
        let n = b0[0].len();
        let groups = n.div_ceil(4);
        let mut lit = 0usize;
        let mut mass: Vec<(f64, u32)> = Vec::new();
        for g in 0..groups {
            if !group_lit(b0, g) {
                continue;
            }
            lit += 1;
            let e: f64 = (4 * g..(4 * g + 4).min(n))
                .map(|j| {
                    (0..3)
                        .map(|c| weights[c][j] * f64::from(b0[c][j]).abs())
                        .sum::<f64>()
                })
                .sum();
            mass.push((e, g as u32));
        }
        let total: f64 = mass.iter().map(|m| m.0).sum();
        mass.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        // An infinite or NaN total (an input that overflowed) culls
        // nothing but zero columns: its product is not finite either, and
        // dropping a group of infinite mass within an infinite budget
        // would turn it into zeros.
        let budget = if total.is_finite() {
            eps.max(0.0) * total
        } else {
            0.0
        };
        let mut dropped = 0.0f64;
        let mut group = vec![false; groups];
        for &(e, g) in &mass {
            // A NaN mass (a NaN in `b0`) is never dropped: it sorts last
            // and fails the comparison.
            if e == 0.0 || dropped + e <= budget {
                dropped += e;
            } else {
                group[g as usize] = true;
            }
        }
        let columns = ActiveColumns::from_groups(&group, tile);
        Culled {
            culled_groups: lit - columns.active_groups,
            dropped_mass: dropped,
            mass: total,
            columns,
        }
    }

    /// The columns of the groups flagged in `group`.
    fn from_groups(group: &[bool], tile: usize) -> ActiveColumns {
        let per_tile = (tile / 4).clamp(1, 64);
        let mask: Vec<u64> = group
            .chunks(per_tile)
            .map(|c| {
                c.iter()
                    .enumerate()
                    .fold(0, |m, (l, &a)| m | (u64::from(a) << l))
            })
            .collect();
        ActiveColumns {
            active_groups: group.iter().filter(|&&a| a).count(),
            tiles: (0..mask.len() as u32)
                .filter(|&t| mask[t as usize] != 0)
                .collect(),
            mask,
        }
    }
}

/// Whether some channel of `b0` is non-zero in group `g`'s columns.
fn group_lit(b0: [&[f32]; 3], g: usize) -> bool {
    let n = b0[0].len();
    (4 * g..(4 * g + 4).min(n)).any(|j| b0.iter().any(|c| c[j] != 0.0))
}

/// [`ActiveColumns::culled`]'s choice.
#[derive(Clone, Debug, PartialEq)]
pub struct Culled {
    /// The groups kept.
    pub columns: ActiveColumns,
    /// Groups with a non-zero `b0` that were dropped.
    pub culled_groups: usize,
    /// The dropped groups' bound on the product's L1 norm (at most `eps`
    /// times `mass`), and the bound's total `E`.
    pub dropped_mass: f64,
    pub mass: f64,
}

/// The `k` lowest bits set (all 64 from `k = 64` on).
fn low_bits(k: usize) -> u64 {
    if k >= 64 {
        u64::MAX
    } else {
        (1u64 << k) - 1
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
    /// Matrix entries (positions, each with its stored channels) decoded
    /// and multiplied.
    pub entries: u64,
    /// Sparse entries read and multiplied (those of active column groups).
    pub sparse_entries: u64,
    /// Set by the run time's culling of negligible columns
    /// ([`ActiveColumns::culled`], through `Runtime::product_over`; 0 from
    /// the gather itself): column groups with a non-zero input dropped,
    /// their bound on the product's L1 norm, and the bound's total.
    pub culled_groups: u64,
    pub culled_mass: f64,
    pub mass: f64,
}

impl GatherStats {
    /// The stats of two parts of a product together.
    fn add(self, o: GatherStats) -> GatherStats {
        GatherStats {
            bytes_read: self.bytes_read + o.bytes_read,
            tiles_touched: self.tiles_touched + o.tiles_touched,
            tiles_skipped: self.tiles_skipped + o.tiles_skipped,
            entries: self.entries + o.entries,
            sparse_entries: self.sparse_entries + o.sparse_entries,
            culled_groups: self.culled_groups + o.culled_groups,
            culled_mass: self.culled_mass + o.culled_mass,
            mass: self.mass + o.mass,
        }
    }
}

/// A compressed matrix laid out for the CPU gather.
pub struct CompressedGather {
    n: usize,
    image: usize,
    tile: usize,
    format: DenseFormat,
    channels: usize,
    /// Stored tiles, each re-laid block column by block column (BC1, BC4)
    /// or as in the file (other formats).
    dense: Vec<u8>,
    row_start: Vec<u32>,
    cols: Vec<u16>,
    offsets: Vec<u32>,
    /// `slot_of[tr * tiles_per_side + tc]`: the slot of stored tile
    /// (tr, tc), [`NONE`] where it is not stored.
    slot_of: Vec<u32>,
    tiles_per_side: usize,
    bc1: Option<[Bc1Table; 3]>,
    /// BC4: value of numerator `k` of the 8-level (`/7`) and 6-level (`/5`)
    /// interpolations, per channel.
    bc4_7: Vec<[f32; 1786]>,
    bc4_5: Vec<[f32; 1276]>,
    /// A grey (one-channel) BC4 matrix on AVX-512: the 8 levels of every
    /// endpoint pair, `[r0 << 8 | r1]` (2 MiB, so a block's palette is one
    /// load; empty otherwise).
    bc4_pairs: Vec<[f32; 8]>,
    book: Codebook,
    sparse: SparseRt,
    /// [`Encoded::col_scale`] (empty: none).
    col_scale: Vec<f32>,
    bytes_index: u64,
    simd: bool,
    /// [`simd_kind`] where `simd`, else "none": decided once, not per
    /// block column.
    vector: &'static str,
    /// The f16 and f32 kernel ([`float`]).
    float_kernel: float::FloatKernel,
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
                    float::relay_tile(e.format, src, h, w, e.channels, &mut dense);
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
        let mut slot_of = vec![NONE; tps * tps];
        for tr in 0..tps {
            for slot in e.index.row_start[tr] as usize..e.index.row_start[tr + 1] as usize {
                slot_of[tr * tps + e.index.cols[slot] as usize] = slot as u32;
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
                Bc1Table { values }
            })
        });
        let (mut bc4_7, mut bc4_5) = (Vec::new(), Vec::new());
        if e.format == DenseFormat::Bc4 {
            for c in 0..e.channels {
                let (t7, t5) = bc4_levels(e.scale[c], e.log_range);
                bc4_7.push(t7);
                bc4_5.push(t5);
            }
        }
        let bc4_pairs =
            if e.format == DenseFormat::Bc4 && e.channels == 1 && simd && simd_kind() == "avx512" {
                (0..1usize << 16)
                    .map(|k| bc4_palette(&bc4_7[0], &bc4_5[0], (k >> 8) as u8, k as u8))
                    .collect()
            } else {
                Vec::new()
            };
        let sparse = SparseRt::new(e, tile, tps);
        CompressedGather {
            n: e.n,
            image: e.image_size,
            tile,
            format: e.format,
            channels: e.channels,
            dense,
            row_start: e.index.row_start.clone(),
            cols: e.index.cols.clone(),
            offsets,
            slot_of,
            tiles_per_side: tps,
            bc1,
            bc4_7,
            bc4_5,
            bc4_pairs,
            book,
            sparse,
            col_scale: e.col_scale.clone(),
            bytes_index: e.bytes_index() as u64,
            simd: simd && simd_available(),
            vector: if simd { simd_kind() } else { "none" },
            float_kernel: float::FloatKernel::for_cpu(if simd { simd_kind() } else { "none" }),
        }
    }

    /// The same gather on the AVX2 kernels where the CPU has AVX2 and FMA
    /// (unchanged elsewhere): an AVX-512 host then tests them too.
    pub fn on_avx2(mut self) -> CompressedGather {
        if self.simd && simd_kind() != "none" {
            self.vector = "avx2";
            self.float_kernel = float::FloatKernel::for_cpu("avx2");
            // The grey AVX-512 kernel's table: its absence selects the
            // compiled-for-AVX2 grey path, as on an AVX2 host.
            self.bc4_pairs = Vec::new();
        }
        self
    }

    /// The vector kernels this gather runs: "avx512", "avx2" or "none".
    pub fn vector_kind(&self) -> &'static str {
        self.vector
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
        // Column scales: the stored matrix multiplies s ∘ B0 (zero where
        // B0 is, so the active groups are the same).
        // Into a buffer kept by the calling thread (as the `B0` buffers
        // below), each channel one f32 product per value as
        // [`radiosity_bakefile::codec::scaled_input`] computes it.
        let mut scaled = SCALED.take();
        let b0 = if self.col_scale.is_empty() {
            b0
        } else {
            for (out, b) in scaled.iter_mut().zip(b0) {
                out.clear();
                out.extend(b.iter().zip(&self.col_scale).map(|(x, s)| x * s));
            }
            [&scaled[0][..], &scaled[1][..], &scaled[2][..]]
        };
        let grey_b0 = same_values(b0[0], b0[1]) && same_values(b0[1], b0[2]);
        // Channels of B0 to multiply: one when both the matrix and B0 are grey.
        let out_ch = if self.channels == 1 && grey_b0 { 1 } else { 3 };
        let tile = self.tile;
        // The vector BC1 paths read B0 by group of 4 columns, padded; the sparse
        // part's common case by column, channels side by side. Both are
        // written for the active groups only (the only ones read), into
        // buffers kept by the calling thread between products: taken out
        // and put back, so that a nested product (a rayon worker running
        // another gather while it waits) gets buffers of its own.
        let (mut b0p, mut b0x) = INPUTS.take();
        b0p.clear();
        b0x.clear();
        if self.simd && (self.format == DenseFormat::Bc1 || !self.bc4_pairs.is_empty()) {
            fill_b0_groups(b0, active, tile, &mut b0p);
        }
        if out_ch == 3 && !self.sparse.is_empty() {
            fill_b0_columns(b0, active, tile, &mut b0x);
        }
        let inputs = RowInputs {
            b0,
            b0p: &b0p,
            b0x: &b0x,
            active,
            out_ch,
            sparse_avx2: self.simd && sparse_avx2_available(),
        };
        // Rows of H, written in place by rows of tiles (one allocation per
        // product: a spot light's gather is short enough for per-row
        // allocations to show).
        let mut out = vec![[0.0f32; 4]; self.image];
        let row = |(tr, rows): (usize, &mut [[f32; 4]])| {
            SCRATCH.with_borrow_mut(|sc| self.tile_row(tr, &inputs, rows, sc))
        };
        // A product with little to do runs on the calling thread: handing
        // rows to the pool and joining costs 20–30 µs on the 2-core host
        // (futex wake-ups under virtualisation), more than such a product
        // takes alone. The rows and their sums are the same either way.
        let positions = 4 * active.active_groups as u64 * self.image as u64;
        let mut stats = if positions <= SEQUENTIAL_POSITIONS {
            out.chunks_mut(tile)
                .enumerate()
                .map(row)
                .fold(GatherStats::default(), GatherStats::add)
        } else {
            rows_shared(&mut out, tile, row)
        };
        INPUTS.set((b0p, b0x));
        stats.bytes_read += self.bytes_index;
        for (i, v) in out.iter().take(n).enumerate() {
            for c in 0..3 {
                h[c][i] = v[c.min(out_ch - 1)];
            }
        }
        SCALED.set(scaled);
        stats
    }

    /// One row of tiles: its rows of `H` (dense, then sparse; the fourth
    /// lane is padding).
    fn tile_row(
        &self,
        tr: usize,
        inputs: &RowInputs,
        rows: &mut [[f32; 4]],
        scratch: &mut RowScratch,
    ) -> GatherStats {
        let RowInputs {
            b0,
            b0p,
            active,
            out_ch,
            ..
        } = *inputs;
        let tile = self.tile;
        let h = tile.min(self.image - tr * tile);
        let mut stats = GatherStats::default();
        let RowScratch {
            acc,
            fast_cols,
            keys,
            keys512,
            visit,
            runs,
            wide,
        } = scratch;
        wide.resize(256, [0.0; 4]);
        runs.clear();
        // This row's stored tiles in active tile columns, listed without
        // branches (each slot written, the count advanced by its flag):
        // testing every stored tile costs branches a predictor misses when
        // few columns are lit, and visiting only the active tile columns
        // makes a gather with few of them cost in proportion.
        let stored = (self.row_start[tr + 1] - self.row_start[tr]) as u64;
        let row_of = &self.slot_of[tr * self.tiles_per_side..(tr + 1) * self.tiles_per_side];
        let touched = compact(visit, &active.tiles, row_of);
        'dense: {
            // Per block row and output channel: 16 lanes (row r, column
            // c of the block at lane 4r + c). An f16 or f32 tile may end
            // in a partial block (padded with zeros at load).
            let bh = h.div_ceil(4);
            acc.clear();
            acc.resize(bh, [[0.0f32; 16]; 3]);
            // BC1 rows of tiles run in one vector call (on AVX-512 with
            // the 24 accumulators of 8 block rows in registers, so for
            // tiles of at most 32 rows, the encoder's; larger tiles,
            // which the reader accepts, take the portable path there):
            // the active block columns (byte offset, first column) are
            // listed first.
            // A grey BC4 matrix runs the same way on AVX-512
            // ([`x86::bc4_grey_row_avx512`]).
            let grey_fast = !self.bc4_pairs.is_empty() && bh <= 8;
            let fast = grey_fast
                || (self.simd
                    && self.format == DenseFormat::Bc1
                    && (self.vector == "avx2" || bh <= 8));
            fast_cols.clear();
            // Nothing active in this row of tiles: its rows of H stay 0
            // (before the sparse part) and no kernel is entered.
            if touched == 0 {
                break 'dense;
            }
            if fast {
                // Only the list: counted by its length afterwards.
                for &slot in &visit[..touched] {
                    let slot = slot as usize;
                    let tc = self.cols[slot] as usize;
                    let bw = tile.min(self.image - tc * tile) / 4;
                    let base = self.offsets[slot] as usize;
                    let (c0, col_bytes) = (tc * tile, 8 * bh);
                    let mut bits = active.mask[tc] & low_bits(bw);
                    while bits != 0 {
                        let bc = bits.trailing_zeros() as usize;
                        bits &= bits - 1;
                        fast_cols.push(((base + bc * col_bytes) as u32, (c0 + 4 * bc) as u32));
                    }
                }
                let k = fast_cols.len();
                stats.bytes_read += (k * 8 * bh) as u64;
                stats.entries += (k * 16 * bh) as u64;
            }
            for &slot in &visit[..if fast { 0 } else { touched }] {
                let slot = slot as usize;
                let tc = self.cols[slot] as usize;
                let w = tile.min(self.image - tc * tile);
                let bw = w.div_ceil(4);
                let col_bytes = match self.format {
                    DenseFormat::Bc1 => 8 * bh,
                    DenseFormat::Bc4 => 8 * self.channels * bh,
                    f => float::column_bytes(f, bh, self.channels),
                };
                let base = self.offsets[slot] as usize;
                // The tile's active block columns, by their set bits.
                let mut bits = active.mask[tc] & low_bits(bw);
                stats.bytes_read += (bits.count_ones() as usize * col_bytes) as u64;
                stats.entries += (bits.count_ones() as usize * 16 * bh) as u64;
                while bits != 0 {
                    let bc = bits.trailing_zeros() as usize;
                    bits &= bits - 1;
                    let c0 = tc * tile + 4 * bc;
                    let mut b = [[0.0f32; 4]; 3];
                    for (ch, bch) in b.iter_mut().enumerate().take(out_ch) {
                        for (k, v) in bch.iter_mut().enumerate() {
                            *v = b0[ch].get(c0 + k).copied().unwrap_or(0.0);
                        }
                    }
                    let col = &self.dense[base + bc * col_bytes..base + (bc + 1) * col_bytes];
                    match self.format {
                        DenseFormat::Bc1 => self.bc1_column(col, &b, acc),
                        DenseFormat::Bc4 => self.bc4_column_dispatch(col, &b, out_ch, acc),
                        f => {
                            // The stored scale (1 for f32) into B0:
                            // a power of two, so exact.
                            for (oc, bc) in b.iter_mut().enumerate().take(out_ch) {
                                let s = self.book.inv_scale[oc.min(self.channels - 1)];
                                if f != DenseFormat::F32 {
                                    bc.iter_mut().for_each(|v| *v *= s);
                                }
                            }
                            let (k, c) = (self.float_kernel, self.channels);
                            float::column(k, f, col, c, &b, out_ch, acc);
                        }
                    }
                }
            }
            #[cfg(target_arch = "x86_64")]
            if grey_fast {
                let (d, cols, p) = (&self.dense[..], &fast_cols[..], &self.bc4_pairs[..]);
                // SAFETY: the pair table is built only where the CPU
                // reports AVX-512F.
                unsafe {
                    if out_ch == 3 {
                        bc4_grey_row::<3>(bh, d, cols, b0p, p, acc);
                    } else {
                        bc4_grey_row::<1>(bh, d, cols, b0p, p, acc);
                    }
                }
            } else if fast && self.vector == "avx2" {
                // SAFETY: `simd_kind` checked AVX2 and FMA.
                unsafe {
                    let tables = self.bc1.as_ref().expect("BC1 tables");
                    x86::bc1_row_avx2(&self.dense, fast_cols, b0p, tables, keys, acc);
                }
            } else if fast {
                // SAFETY: `simd` is set only when the CPU reports AVX-512F.
                unsafe {
                    let tables = self.bc1.as_ref().expect("BC1 tables");
                    let (d, cols) = (&self.dense[..], &fast_cols[..]);
                    let acc = &mut acc[..];
                    // The common full row of tiles (8 block rows) with
                    // its accumulators in registers; the last, shorter
                    // one through the same code with fewer rows.
                    match bh {
                        8 => x86::bc1_row_avx512::<8>(d, cols, b0p, tables, keys512, acc),
                        7 => x86::bc1_row_avx512::<7>(d, cols, b0p, tables, keys512, acc),
                        6 => x86::bc1_row_avx512::<6>(d, cols, b0p, tables, keys512, acc),
                        5 => x86::bc1_row_avx512::<5>(d, cols, b0p, tables, keys512, acc),
                        4 => x86::bc1_row_avx512::<4>(d, cols, b0p, tables, keys512, acc),
                        3 => x86::bc1_row_avx512::<3>(d, cols, b0p, tables, keys512, acc),
                        2 => x86::bc1_row_avx512::<2>(d, cols, b0p, tables, keys512, acc),
                        _ => x86::bc1_row_avx512::<1>(d, cols, b0p, tables, keys512, acc),
                    }
                };
            }
            for (br, a) in acc.iter().enumerate() {
                for (r, row) in rows.iter_mut().skip(4 * br).take(4).enumerate() {
                    for (ch, o) in row.iter_mut().enumerate().take(out_ch) {
                        let l = &a[ch][4 * r..4 * r + 4];
                        *o = (l[0] + l[1]) + (l[2] + l[3]);
                    }
                }
            }
        }
        stats.tiles_touched = touched as u64;
        stats.tiles_skipped = stored - touched as u64;
        // The sparse part of these rows.
        self.sparse.row(
            tr,
            self.tiles_per_side,
            tile,
            inputs,
            rows,
            visit,
            runs,
            wide,
            &mut stats,
        );
        stats
    }

    /// One BC1 block column (`bh` blocks) times `b`, into `acc`.
    fn bc1_column(&self, col: &[u8], b: &[[f32; 4]; 3], acc: &mut [[[f32; 16]; 3]]) {
        let tables = self.bc1.as_ref().expect("BC1 tables");
        for (k, a) in acc.iter_mut().enumerate() {
            let word = u64::from_le_bytes(col[8 * k..8 * k + 8].try_into().expect("8 bytes"));
            let keys = bc1_keys(word);
            let idx = keys[3];
            for ch in 0..3 {
                let pal = &tables[ch].values[keys[ch] as usize];
                for (lane, v) in a[ch].iter_mut().enumerate() {
                    let q = (idx >> (2 * lane)) & 3;
                    *v += pal[q as usize] * b[ch][lane & 3];
                }
            }
        }
    }

    /// [`Self::bc4_column`] compiled for the widest vectors this CPU has
    /// (with `simd`): the same Rust, so the same operations in the same
    /// order and the same bits (Rust does not fuse a multiply and an add
    /// on its own); its per-channel loops then take one or two vector
    /// instructions where the baseline's SSE2 takes four (a grey matrix
    /// gathering coloured light on the Cornell box at 1k patches, before it
    /// had its own row kernel, on AVX-512: 0.41 → 0.34 ms; the AVX2 build
    /// is not measured, no AVX2-only host being at hand). 3-channel BC4
    /// and tiles over 32 rows run here.
    fn bc4_column_dispatch(
        &self,
        col: &[u8],
        b: &[[f32; 4]; 3],
        out_ch: usize,
        acc: &mut [[[f32; 16]; 3]],
    ) {
        #[cfg(target_arch = "x86_64")]
        match self.vector {
            // SAFETY: `vector` names what the CPU reported at `new`.
            "avx512" => return unsafe { self.bc4_column_avx512(col, b, out_ch, acc) },
            // SAFETY: as above (AVX2 and FMA).
            "avx2" => return unsafe { self.bc4_column_avx2(col, b, out_ch, acc) },
            _ => {}
        }
        self.bc4_column(col, b, out_ch, acc);
    }

    /// [`Self::bc4_column`] with AVX-512F.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    unsafe fn bc4_column_avx512(
        &self,
        col: &[u8],
        b: &[[f32; 4]; 3],
        out_ch: usize,
        acc: &mut [[[f32; 16]; 3]],
    ) {
        // SAFETY: this function runs only where the CPU has AVX-512F.
        self.bc4_column_with(col, b, out_ch, acc, |pal, bits| unsafe {
            x86::bc4_values_avx512(pal, bits)
        });
    }

    /// [`Self::bc4_column`] with AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn bc4_column_avx2(
        &self,
        col: &[u8],
        b: &[[f32; 4]; 3],
        out_ch: usize,
        acc: &mut [[[f32; 16]; 3]],
    ) {
        self.bc4_column(col, b, out_ch, acc);
    }

    /// One BC4 block column (`bh` blocks of `channels` channels) times `b`.
    #[inline(always)]
    fn bc4_column(&self, col: &[u8], b: &[[f32; 4]; 3], out_ch: usize, acc: &mut [[[f32; 16]; 3]]) {
        self.bc4_column_with(col, b, out_ch, acc, |pal, bits| {
            std::array::from_fn(|lane| pal[((bits >> (3 * lane)) & 7) as usize])
        });
    }

    /// [`Self::bc4_column`] with a block's 16 values picked from its
    /// palette by `values` (lane `l`: entry `(bits >> 3l) & 7`).
    #[inline(always)]
    fn bc4_column_with(
        &self,
        col: &[u8],
        b: &[[f32; 4]; 3],
        out_ch: usize,
        acc: &mut [[[f32; 16]; 3]],
        values: impl Fn(&[f32; 8], u64) -> [f32; 16],
    ) {
        let chs = self.channels;
        for (k, a) in acc.iter_mut().enumerate() {
            for c in 0..chs {
                let blk = &col[8 * (k * chs + c)..8 * (k * chs + c) + 8];
                let pal = bc4_palette(&self.bc4_7[c], &self.bc4_5[c], blk[0], blk[1]);
                let bits = u64::from_le_bytes(blk.try_into().unwrap()) >> 16;
                // The block's 16 values once, then per output channel a
                // loop the compiler vectorises (a grey matrix serves three
                // channels of B0 from one decode: picking the palette
                // entry per lane and channel had been most of its time,
                // 3.7× the 3-channel BC1 gather on the Cornell box at 1k).
                let vals = values(&pal, bits);
                // One stored channel serves every output channel.
                let outs: &[usize] = if chs == 1 {
                    &[0, 1, 2][..out_ch]
                } else {
                    &[0, 1, 2][c..c + 1]
                };
                for &oc in outs {
                    let bo = &b[oc];
                    for (lane, (v, x)) in a[oc].iter_mut().zip(&vals).enumerate() {
                        *v += x * bo[lane & 3];
                    }
                }
            }
        }
    }
}

/// Rows of a tile (at most 256) as the sparse loops index them, by the
/// high byte of an entry's position.
type Rows = [[f32; 4]; 256];

/// The 256 columns of `B0` (by column, channels side by side) from a
/// tile's first column `jb`, as the sparse loops index them by the low
/// byte of an entry's position: [`sparse::fill_b0_columns`] pads `b0x`
/// so that this never fails.
#[inline(always)]
fn tile_columns(b0x: &[[f32; 4]], jb: u32) -> &[[f32; 4]; 256] {
    b0x[jb as usize..jb as usize + 256]
        .try_into()
        .expect("B0 padded by 256 columns")
}

/// What every row of tiles of one product reads besides the matrix.
#[derive(Clone, Copy)]
struct RowInputs<'a> {
    b0: [&'a [f32]; 3],
    /// [`fill_b0_groups`]'s buffer where a vector BC1 path runs, else empty.
    b0p: &'a [[[f32; 4]; 3]],
    /// `B0` by column, channels side by side, where [`sparse_rgb9e5`] or
    /// [`sparse_values`] runs (three output channels), else empty.
    b0x: &'a [[f32; 4]],
    active: &'a ActiveColumns,
    /// Channels multiplied: 1 when the matrix and `B0` are both grey.
    out_ch: usize,
    /// [`x86::sparse_rgb9e5_avx2`] runs (the vectorised path, on a CPU with
    /// AVX2).
    sparse_avx2: bool,
}

/// Buffers of one thread's rows of tiles, kept between rows and products
/// (allocating them per row showed in a spot light's short gather).
#[derive(Default)]
struct RowScratch {
    /// Per block row and output channel: 16 lanes.
    acc: Vec<[[f32; 16]; 3]>,
    /// The active block columns of the row (byte offset, first column).
    fast_cols: Vec<(u32, u32)>,
    /// [`x86::bc1_row_avx2`]'s palette keys.
    keys: Vec<u32>,
    /// [`x86::bc1_row_avx512`]'s palette keys.
    keys512: Vec<[[u32; 16]; 2]>,
    /// The row's stored tiles (then sparse blocks) to visit ([`compact`]).
    visit: Vec<u32>,
    /// The sparse part's common case: runs of entries (first, end, first
    /// column of their tile) for [`sparse_rgb9e5`] or [`sparse_values`].
    runs: Vec<[u32; 3]>,
    /// The sparse loops' 256 rows ([`Rows`]).
    wide: Vec<[f32; 4]>,
}

/// Lists into `out` the entries of `row_of` (a row's slots by tile
/// column, [`NONE`] where none) at the active tile columns `tiles`, in
/// order, and returns how many: every slot is written and the count
/// advanced by its flag, without branches.
fn compact(out: &mut Vec<u32>, tiles: &[u32], row_of: &[u32]) -> usize {
    // Entries past the count are stale from earlier rows, never read;
    // the count never passes the item being written.
    if out.len() < tiles.len() {
        out.resize(tiles.len(), 0);
    }
    let mut k = 0;
    for &tc in tiles {
        let slot = row_of[tc as usize];
        out[k] = slot;
        k += usize::from(slot != NONE);
    }
    k
}

/// Runs `row` over the rows of tiles of `out` on the calling thread and
/// `threads − 1` helpers from the pool, each taking the next row from a
/// shared counter: the caller works while a helper wakes, instead of
/// handing every row to the pool and sleeping until they are done. With
/// `par_chunks_mut` a product often ran on one thread alone, the second
/// worker not woken in time: a spot's gather on Sponza at 1,821 patches,
/// repeated, took 0.094 or 0.195 ms from run to run, and takes 0.087–0.092
/// ms this way; in `bench frame`, alternating runs, every column 2–8 %
/// faster on the 2k and 4k bakes, the interior's spot at 2k 0.091–0.094 →
/// 0.080–0.082 ms, the other spots within the noise (`docs/runtime.md`).
/// Each row is computed by one thread from the same inputs, so the result
/// is the same bits whichever thread takes it.
fn rows_shared<F>(out: &mut [[f32; 4]], tile: usize, row: F) -> GatherStats
where
    F: Fn((usize, &mut [[f32; 4]])) -> GatherStats + Sync,
{
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::sync::{Mutex, PoisonError};
    let rows: Vec<Mutex<&mut [[f32; 4]]>> = out.chunks_mut(tile).map(Mutex::new).collect();
    let next = AtomicUsize::new(0);
    let total = Mutex::new(GatherStats::default());
    let work = || {
        let mut s = GatherStats::default();
        loop {
            let tr = next.fetch_add(1, Ordering::Relaxed);
            let Some(r) = rows.get(tr) else { break };
            let mut r = r.lock().unwrap_or_else(PoisonError::into_inner);
            s = s.add(row((tr, &mut r)));
        }
        let mut t = total.lock().unwrap_or_else(PoisonError::into_inner);
        *t = t.add(s);
    };
    let helpers = rayon::current_num_threads().saturating_sub(1).max(1);
    rayon::in_place_scope(|sc| {
        for _ in 0..helpers {
            sc.spawn(|_| work());
        }
        work();
    });
    total.into_inner().unwrap_or_else(PoisonError::into_inner)
}

/// Matrix positions (active columns × rows) up to which a product runs
/// on the calling thread ([`CompressedGather::gather`]): 2^16 positions
/// take about 27 µs on one core of the 2-core host when columns are
/// skipped (the Cornell box at 2k under one spot: 0.136 ms for 323k
/// positions on one thread, 0.056 ms on two), the cost of handing the
/// rows to a second thread and joining.
const SEQUENTIAL_POSITIONS: u64 = 1 << 16;

/// [`x86::bc4_grey_row_avx512`] for a row of tiles of `bh` (1 to 8) block
/// rows and `CH` channels of `B0`.
///
/// # Safety
/// The CPU must have AVX-512F.
#[cfg(target_arch = "x86_64")]
unsafe fn bc4_grey_row<const CH: usize>(
    bh: usize,
    d: &[u8],
    cols: &[(u32, u32)],
    b0p: &[[[f32; 4]; 3]],
    p: &[[f32; 8]],
    acc: &mut [[[f32; 16]; 3]],
) {
    match bh {
        8 => x86::bc4_grey_row_avx512::<8, CH>(d, cols, b0p, p, acc),
        7 => x86::bc4_grey_row_avx512::<7, CH>(d, cols, b0p, p, acc),
        6 => x86::bc4_grey_row_avx512::<6, CH>(d, cols, b0p, p, acc),
        5 => x86::bc4_grey_row_avx512::<5, CH>(d, cols, b0p, p, acc),
        4 => x86::bc4_grey_row_avx512::<4, CH>(d, cols, b0p, p, acc),
        3 => x86::bc4_grey_row_avx512::<3, CH>(d, cols, b0p, p, acc),
        2 => x86::bc4_grey_row_avx512::<2, CH>(d, cols, b0p, p, acc),
        _ => x86::bc4_grey_row_avx512::<1, CH>(d, cols, b0p, p, acc),
    }
}

/// No stored tile or sparse block at this place ([`CompressedGather`]'s
/// tables).
const NONE: u32 = u32::MAX;

/// `B0` by group (the AVX2 kernel's) and by column (the sparse part's).
type B0Buffers = (Vec<[[f32; 4]; 3]>, Vec<[f32; 4]>);

thread_local! {
    static SCRATCH: std::cell::RefCell<RowScratch> = std::cell::RefCell::new(RowScratch::default());
    /// The calling thread's `B0` buffers ([`CompressedGather::gather`]).
    static INPUTS: std::cell::Cell<B0Buffers> = std::cell::Cell::default();
    /// The calling thread's column-scaled `B0` ([`CompressedGather::gather`]).
    static SCALED: std::cell::Cell<[Vec<f32>; 3]> = std::cell::Cell::default();
}

/// `a == b` value by value (as `[f32] == [f32]`: 0 equals −0, NaN nothing),
/// by chunks whose comparisons vectorise, stopping at the first chunk that
/// differs (a coloured `B0` differs early, a grey one is read once).
fn same_values(a: &[f32], b: &[f32]) -> bool {
    if a.len() != b.len() {
        return false;
    }
    let (ca, cb) = (a.chunks(64), b.chunks(64));
    ca.zip(cb)
        .all(|(x, y)| x.iter().zip(y).fold(true, |e, (p, q)| e & (p == q)))
}

/// Whether this CPU runs a vectorised BC1 path (AVX-512, or AVX2 with
/// FMA).
pub fn simd_available() -> bool {
    simd_kind() != "none"
}

/// The vectorised BC1 path this CPU runs: "avx512", "avx2" or "none".
pub fn simd_kind() -> &'static str {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx512f") {
            return "avx512";
        }
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            return "avx2";
        }
        "none"
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        "none"
    }
}

/// The active groups of `active` (group `g` covers columns `4g..4g + 4`;
/// tile column `tc`'s bit `l` is group `tc · tile / 4 + l`), ascending.
fn active_groups(active: &ActiveColumns, tile: usize) -> impl Iterator<Item = usize> + '_ {
    let per_tile = (tile / 4).clamp(1, 64);
    active.tiles.iter().flat_map(move |&tc| {
        let mut bits = active.mask[tc as usize];
        std::iter::from_fn(move || {
            (bits != 0).then(|| {
                let l = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                tc as usize * per_tile + l
            })
        })
    })
}

/// `B0` by group of 4 columns into `out`, the three channels of a group
/// side by side and zero past `n`: what the vector BC1 kernels broadcast
/// per block column, without bounds checks. Only the active groups are
/// written (the others are never read, and keep what they held).
fn fill_b0_groups(
    b0: [&[f32]; 3],
    active: &ActiveColumns,
    tile: usize,
    out: &mut Vec<[[f32; 4]; 3]>,
) {
    let n = b0[0].len();
    out.resize(n.div_ceil(4), [[0.0; 4]; 3]);
    for g in active_groups(active, tile) {
        out[g] = std::array::from_fn(|c| {
            std::array::from_fn(|k| b0[c].get(4 * g + k).copied().unwrap_or(0.0))
        });
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

#[cfg(test)]
mod tests {
    use super::same_values;

    /// The chunked comparison answers as `[f32] == [f32]` does: a
    /// difference in any chunk (the last, partial one too), 0 against −0,
    /// NaN against itself, unequal lengths.
    #[test]
    fn same_values_is_slice_equality() {
        for n in [0usize, 1, 63, 64, 65, 200] {
            let a: Vec<f32> = (0..n).map(|i| i as f32 * 0.5).collect();
            assert!(same_values(&a, &a.clone()));
            for k in [0, n / 2, n.saturating_sub(1)]
                .into_iter()
                .filter(|&k| k < n)
            {
                let mut b = a.clone();
                b[k] += 1.0;
                assert_eq!(same_values(&a, &b), a[..] == b[..], "n {n} k {k}");
                b[k] = if a[k] == 0.0 { -0.0 } else { f32::NAN };
                assert_eq!(same_values(&a, &b), a[..] == b[..], "n {n} k {k}");
                let mut c = a.clone();
                c[k] = f32::NAN;
                assert!(!same_values(&c, &c.clone()));
            }
            assert!(!same_values(&a, &a[..n.saturating_sub(1)]) || n == 0);
        }
    }
}
