//! The gather's BC4 rows: a row of tiles of BC4 blocks (one block per
//! stored channel, the channels of a block side by side) times `B0`. The
//! 8 levels of a block are looked up in a table indexed by the
//! interpolation's numerator, and its 16 values are picked from them once
//! (on AVX-512 by one permute), then multiplied into every channel of `B0`
//! they serve, in code compiled for the CPU's widest vectors. A grey matrix
//! (one BC4 channel) on AVX-512 runs a whole row of tiles in one call
//! ([`super::x86::bc4_grey_row_avx512`]), its accumulators in registers and
//! a block's palette one load from a table of every endpoint pair.

use super::palette::{bc4_levels, bc4_palette};
use super::rows::{DenseRow, DenseScratch, GatherStats};
#[cfg(target_arch = "x86_64")]
use super::x86;

/// A BC4 matrix's level tables and the kernel that runs it.
pub(super) struct Bc4Rows {
    /// Per channel: the value of numerator `k` of the 8-level (`/7`) and
    /// 6-level (`/5`) interpolations.
    t7: Vec<[f32; 1786]>,
    t5: Vec<[f32; 1276]>,
    /// A grey (one-channel) matrix on AVX-512: the 8 levels of every
    /// endpoint pair, `[r0 << 8 | r1]` (2 MiB, so a block's palette is one
    /// load; empty otherwise, which selects the per-column path).
    pairs: Vec<[f32; 8]>,
    channels: usize,
    /// "avx512", "avx2" or "none" (as [`super::bc1::Bc1Rows`]).
    vector: &'static str,
}

impl Bc4Rows {
    /// The tables of a matrix of `channels` stored channels with per
    /// channel scale `scale` and the codec's `log_range`.
    pub(super) fn new(
        scale: &[f32],
        log_range: f32,
        channels: usize,
        vector: &'static str,
    ) -> Bc4Rows {
        let (mut t7, mut t5) = (Vec::new(), Vec::new());
        for &s in &scale[..channels] {
            let (a, b) = bc4_levels(s, log_range);
            t7.push(a);
            t5.push(b);
        }
        let pairs = if channels == 1 && vector == "avx512" {
            (0..1usize << 16)
                .map(|k| bc4_palette(&t7[0], &t5[0], (k >> 8) as u8, k as u8))
                .collect()
        } else {
            Vec::new()
        };
        Bc4Rows {
            t7,
            t5,
            pairs,
            channels,
            vector,
        }
    }

    /// Runs on the AVX2 kernels instead: the pair table's absence selects
    /// the compiled-for-AVX2 grey path, as on an AVX2 host.
    pub(super) fn set_vector(&mut self, vector: &'static str) {
        self.vector = vector;
        if vector != "avx512" {
            self.pairs = Vec::new();
        }
    }

    /// Whether the row runs in one vector call that reads `B0` by group
    /// (a grey matrix on AVX-512, tiles of at most 32 rows).
    pub(super) fn vector_row(&self, bh: usize) -> bool {
        self.reads_groups() && bh <= 8
    }

    /// Whether some row may read `B0` by group.
    pub(super) fn reads_groups(&self) -> bool {
        !self.pairs.is_empty()
    }

    /// `row`'s active block columns times `B0` into `acc` (per block row
    /// and output channel, 16 lanes).
    pub(super) fn row(
        &self,
        row: &DenseRow,
        scratch: &mut DenseScratch,
        acc: &mut [[[f32; 16]; 3]],
        stats: &mut GatherStats,
    ) {
        let out_ch = row.inputs.out_ch;
        if !self.vector_row(row.bh) {
            let col_bytes = 8 * self.channels * row.bh;
            return row.each_column(col_bytes, stats, |col, b| {
                self.column_dispatch(col, b, out_ch, acc)
            });
        }
        row.list_columns(&mut scratch.fast_cols, stats);
        #[cfg(target_arch = "x86_64")]
        {
            let (d, cols, b0p, p) = (
                row.dense,
                &scratch.fast_cols[..],
                row.inputs.b0p,
                &self.pairs[..],
            );
            // SAFETY: the pair table is built only where the CPU reports
            // AVX-512F.
            unsafe {
                if out_ch == 3 {
                    grey_row::<3>(row.bh, d, cols, b0p, p, acc);
                } else {
                    grey_row::<1>(row.bh, d, cols, b0p, p, acc);
                }
            }
        }
    }

    /// [`Self::column`] compiled for the widest vectors this CPU has
    /// (with `simd`): the same Rust, so the same operations in the same
    /// order and the same bits (Rust does not fuse a multiply and an add
    /// on its own); its per-channel loops then take one or two vector
    /// instructions where the baseline's SSE2 takes four (a grey matrix
    /// gathering coloured light on the Cornell box at 1k patches, before it
    /// had its own row kernel, on AVX-512: 0.41 → 0.34 ms; the AVX2 build
    /// is not measured, no AVX2-only host being at hand). 3-channel BC4
    /// and tiles over 32 rows run here.
    fn column_dispatch(
        &self,
        col: &[u8],
        b: &[[f32; 4]; 3],
        out_ch: usize,
        acc: &mut [[[f32; 16]; 3]],
    ) {
        #[cfg(target_arch = "x86_64")]
        match self.vector {
            // SAFETY: `vector` names what the CPU reported at `new`.
            "avx512" => return unsafe { self.column_avx512(col, b, out_ch, acc) },
            // SAFETY: as above (AVX2 and FMA).
            "avx2" => return unsafe { self.column_avx2(col, b, out_ch, acc) },
            _ => {}
        }
        self.column(col, b, out_ch, acc);
    }

    /// [`Self::column`] with AVX-512F.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    unsafe fn column_avx512(
        &self,
        col: &[u8],
        b: &[[f32; 4]; 3],
        out_ch: usize,
        acc: &mut [[[f32; 16]; 3]],
    ) {
        // SAFETY: this function runs only where the CPU has AVX-512F.
        self.column_with(col, b, out_ch, acc, |pal, bits| unsafe {
            x86::bc4_values_avx512(pal, bits)
        });
    }

    /// [`Self::column`] with AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn column_avx2(
        &self,
        col: &[u8],
        b: &[[f32; 4]; 3],
        out_ch: usize,
        acc: &mut [[[f32; 16]; 3]],
    ) {
        self.column(col, b, out_ch, acc);
    }

    /// One BC4 block column (`acc.len()` blocks of `channels` channels)
    /// times `b`: the portable path, the reference of the others.
    #[inline(always)]
    fn column(&self, col: &[u8], b: &[[f32; 4]; 3], out_ch: usize, acc: &mut [[[f32; 16]; 3]]) {
        self.column_with(col, b, out_ch, acc, |pal, bits| {
            std::array::from_fn(|lane| pal[((bits >> (3 * lane)) & 7) as usize])
        });
    }

    /// [`Self::column`] with a block's 16 values picked from its palette
    /// by `values` (lane `l`: entry `(bits >> 3l) & 7`).
    #[inline(always)]
    fn column_with(
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
                let pal = bc4_palette(&self.t7[c], &self.t5[c], blk[0], blk[1]);
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

/// [`x86::bc4_grey_row_avx512`] for a row of tiles of `bh` (1 to 8) block
/// rows and `CH` channels of `B0`.
///
/// # Safety
/// The CPU must have AVX-512F.
#[cfg(target_arch = "x86_64")]
unsafe fn grey_row<const CH: usize>(
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
