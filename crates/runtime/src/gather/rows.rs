//! What every row of tiles of one product shares, whatever the codec:
//! the statistics, the inputs besides the matrix, the thread's scratch,
//! the listing of a row's stored tiles in active columns and the walk of
//! their active block columns. A leaf of the gather, below the codecs'
//! rows ([`super::bc1`], [`super::bc4`], [`super::float`]) and the sparse
//! part ([`super::sparse`]), so that none of them reaches into the parent.

use super::columns::{low_bits, ActiveColumns};

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
    pub(super) fn add(self, o: GatherStats) -> GatherStats {
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

/// Rows of a tile (at most 256) as the sparse loops index them, by the
/// high byte of an entry's position.
pub(super) type Rows = [[f32; 4]; 256];

/// The 256 columns of `B0` (by column, channels side by side) from a
/// tile's first column `jb`, as the sparse loops index them by the low
/// byte of an entry's position: [`super::sparse::fill_b0_columns`] pads `b0x`
/// so that this never fails.
#[inline(always)]
pub(super) fn tile_columns(b0x: &[[f32; 4]], jb: u32) -> &[[f32; 4]; 256] {
    b0x[jb as usize..jb as usize + 256]
        .try_into()
        .expect("B0 padded by 256 columns")
}

/// What every row of tiles of one product reads besides the matrix.
#[derive(Clone, Copy)]
pub(super) struct RowInputs<'a> {
    pub(super) b0: [&'a [f32]; 3],
    /// [`super::columns::fill_b0_groups`]'s buffer where a vector row
    /// kernel runs (BC1, grey BC4), else empty.
    pub(super) b0p: &'a [[[f32; 4]; 3]],
    /// `B0` by column, channels side by side, where the sparse part's
    /// common case runs (three output channels), else empty.
    pub(super) b0x: &'a [[f32; 4]],
    pub(super) active: &'a ActiveColumns,
    /// Channels multiplied: 1 when the matrix and `B0` are both grey.
    pub(super) out_ch: usize,
    /// The sparse part's AVX2 loop runs (the vectorised path, on a CPU
    /// with AVX2).
    pub(super) sparse_avx2: bool,
}

/// Buffers of one thread's rows of tiles, kept between rows and products
/// (allocating them per row showed in a spot light's short gather).
#[derive(Default)]
pub(super) struct RowScratch {
    /// Per block row and output channel: 16 lanes.
    pub(super) acc: Vec<[[f32; 16]; 3]>,
    /// What the codecs' row kernels keep.
    pub(super) dense: DenseScratch,
    /// The row's stored tiles (then sparse blocks) to visit ([`compact`]).
    pub(super) visit: Vec<u32>,
    /// The sparse part's common case: runs of entries (first, end, first
    /// column of their tile).
    pub(super) runs: Vec<[u32; 3]>,
    /// The sparse loops' 256 rows ([`Rows`]).
    pub(super) wide: Vec<[f32; 4]>,
}

/// The codecs' row kernels' buffers.
#[derive(Default)]
pub(super) struct DenseScratch {
    /// The active block columns of the row (byte offset, first column).
    pub(super) fast_cols: Vec<(u32, u32)>,
    /// The AVX2 BC1 row's palette keys.
    pub(super) keys: Vec<u32>,
    /// The AVX-512 BC1 row's palette keys.
    pub(super) keys512: Vec<[[u32; 16]; 2]>,
}

/// One row of tiles' stored tiles in active tile columns, as a codec's
/// row kernel walks them: the re-laid tiles (each block column
/// contiguous) and where each starts.
pub(super) struct DenseRow<'a> {
    /// Every stored tile, re-laid by block column.
    pub(super) dense: &'a [u8],
    /// The row's stored tiles to visit (slots, [`compact`]).
    pub(super) slots: &'a [u32],
    /// Per slot: its tile column, and its first byte in `dense`.
    pub(super) cols: &'a [u16],
    pub(super) offsets: &'a [u32],
    pub(super) tile: usize,
    /// Matrix image size (the last tile column may be narrower).
    pub(super) image: usize,
    /// Block rows of this row of tiles.
    pub(super) bh: usize,
    pub(super) inputs: &'a RowInputs<'a>,
}

impl DenseRow<'_> {
    /// Calls `f` with each active block column of the visited tiles (its
    /// `col_bytes` bytes) and its 4 values of `B0` per output channel
    /// (zero past `n`), in order; counts the bytes and entries read.
    pub(super) fn each_column(
        &self,
        col_bytes: usize,
        stats: &mut GatherStats,
        mut f: impl FnMut(&[u8], &[[f32; 4]; 3]),
    ) {
        let RowInputs {
            b0, active, out_ch, ..
        } = *self.inputs;
        for &slot in self.slots {
            let slot = slot as usize;
            let tc = self.cols[slot] as usize;
            let w = self.tile.min(self.image - tc * self.tile);
            let bw = w.div_ceil(4);
            let base = self.offsets[slot] as usize;
            // The tile's active block columns, by their set bits.
            let mut bits = active.mask[tc] & low_bits(bw);
            stats.bytes_read += (bits.count_ones() as usize * col_bytes) as u64;
            stats.entries += (bits.count_ones() as usize * 16 * self.bh) as u64;
            while bits != 0 {
                let bc = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                let c0 = tc * self.tile + 4 * bc;
                let mut b = [[0.0f32; 4]; 3];
                for (ch, bch) in b.iter_mut().enumerate().take(out_ch) {
                    for (k, v) in bch.iter_mut().enumerate() {
                        *v = b0[ch].get(c0 + k).copied().unwrap_or(0.0);
                    }
                }
                f(
                    &self.dense[base + bc * col_bytes..base + (bc + 1) * col_bytes],
                    &b,
                );
            }
        }
    }

    /// Lists into `out` the active block columns (byte offset, first
    /// column) of the visited tiles of a format of 8 bytes per block, for
    /// a vector row kernel that reads `B0` by group; counts the bytes and
    /// entries read.
    pub(super) fn list_columns(&self, out: &mut Vec<(u32, u32)>, stats: &mut GatherStats) {
        let (tile, bh) = (self.tile, self.bh);
        let active = self.inputs.active;
        out.clear();
        for &slot in self.slots {
            let slot = slot as usize;
            let tc = self.cols[slot] as usize;
            let bw = tile.min(self.image - tc * tile) / 4;
            let base = self.offsets[slot] as usize;
            let (c0, col_bytes) = (tc * tile, 8 * bh);
            let mut bits = active.mask[tc] & low_bits(bw);
            while bits != 0 {
                let bc = bits.trailing_zeros() as usize;
                bits &= bits - 1;
                out.push(((base + bc * col_bytes) as u32, (c0 + 4 * bc) as u32));
            }
        }
        let k = out.len();
        stats.bytes_read += (k * 8 * bh) as u64;
        stats.entries += (k * 16 * bh) as u64;
    }
}

/// Lists into `out` the entries of `row_of` (a row's slots by tile
/// column, [`NONE`] where none) at the active tile columns `tiles`, in
/// order, and returns how many: every slot is written and the count
/// advanced by its flag, without branches.
pub(super) fn compact(out: &mut Vec<u32>, tiles: &[u32], row_of: &[u32]) -> usize {
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

/// No stored tile or sparse block at this place ([`super::CompressedGather`]'s
/// tables).
pub(super) const NONE: u32 = u32::MAX;
