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
pub use columns::{ActiveColumns, Culled};
pub use palette::bc4_levels;
use radiosity_bakefile::codec::{DenseFormat, Encoded};
use rayon::prelude::*;
pub use rows::GatherStats;
use rows::{compact, DenseRow, RowInputs, RowScratch, NONE};
pub use sparse::rgb9e5_factors;
use sparse::{fill_b0_columns, sparse_avx2_available, SparseRt};

mod bc1;
mod bc4;
mod bc6h;
mod columns;
mod float;
mod palette;
mod rows;
mod sparse;
#[cfg(target_arch = "x86_64")]
mod x86;

/// The dense tiles' codec as the gather runs it: each decodes its block
/// columns fused with the multiply-add, on its own kernels.
enum DenseRows {
    Bc1(bc1::Bc1Rows),
    Bc4(bc4::Bc4Rows),
    Float(float::FloatRows),
}

impl DenseRows {
    /// Whether a row of `bh` block rows may read `B0` by group
    /// ([`columns::fill_b0_groups`]), so that the buffer must be filled.
    fn reads_groups(&self) -> bool {
        match self {
            DenseRows::Bc1(k) => k.vector_row(8),
            DenseRows::Bc4(k) => k.reads_groups(),
            DenseRows::Float(_) => false,
        }
    }
}

/// A compressed matrix laid out for the CPU gather.
pub struct CompressedGather {
    n: usize,
    image: usize,
    tile: usize,
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
    /// The codec's decoding tables and kernels.
    rows: DenseRows,
    sparse: SparseRt,
    /// [`Encoded::col_scale`] (empty: none).
    col_scale: Vec<f32>,
    bytes_index: u64,
    simd: bool,
    /// [`simd_kind`] where `simd`, else "none": decided once, not per
    /// block column.
    vector: &'static str,
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
        let vector = if simd { simd_kind() } else { "none" };
        let rows = match e.format {
            DenseFormat::Bc1 => DenseRows::Bc1(bc1::Bc1Rows::new(&book, vector)),
            DenseFormat::Bc4 => {
                DenseRows::Bc4(bc4::Bc4Rows::new(&e.scale, e.log_range, e.channels, vector))
            }
            f => DenseRows::Float(float::FloatRows::new(f, e.channels, book.inv_scale, vector)),
        };
        let sparse = SparseRt::new(e, tile, tps);
        CompressedGather {
            n: e.n,
            image: e.image_size,
            tile,
            channels: e.channels,
            dense,
            row_start: e.index.row_start.clone(),
            cols: e.index.cols.clone(),
            offsets,
            slot_of,
            tiles_per_side: tps,
            rows,
            sparse,
            col_scale: e.col_scale.clone(),
            bytes_index: e.bytes_index() as u64,
            simd: simd && simd_available(),
            vector,
        }
    }

    /// The same gather on the AVX2 kernels where the CPU has AVX2 and FMA
    /// (unchanged elsewhere): an AVX-512 host then tests them too.
    pub fn on_avx2(mut self) -> CompressedGather {
        if self.simd && simd_kind() != "none" {
            self.vector = "avx2";
            match &mut self.rows {
                DenseRows::Bc1(k) => k.set_vector("avx2"),
                DenseRows::Bc4(k) => k.set_vector("avx2"),
                DenseRows::Float(k) => k.set_vector("avx2"),
            }
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
        if self.rows.reads_groups() {
            columns::fill_b0_groups(b0, active, tile, &mut b0p);
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
        let RowInputs { active, out_ch, .. } = *inputs;
        let tile = self.tile;
        let h = tile.min(self.image - tr * tile);
        let mut stats = GatherStats::default();
        let RowScratch {
            acc,
            dense,
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
        // Nothing active in this row of tiles: its rows of H stay 0
        // (before the sparse part) and no kernel is entered.
        if touched > 0 {
            // Per block row and output channel: 16 lanes (row r, column
            // c of the block at lane 4r + c).
            let bh = h.div_ceil(4);
            acc.clear();
            acc.resize(bh, [[0.0f32; 16]; 3]);
            let row = DenseRow {
                dense: &self.dense,
                slots: &visit[..touched],
                cols: &self.cols,
                offsets: &self.offsets,
                tile,
                image: self.image,
                bh,
                inputs,
            };
            match &self.rows {
                DenseRows::Bc1(k) => k.row(&row, dense, acc, &mut stats),
                DenseRows::Bc4(k) => k.row(&row, dense, acc, &mut stats),
                DenseRows::Float(k) => k.row(&row, acc, &mut stats),
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
