//! The gather's BC1 rows: a row of tiles of BC1 blocks (one channel per
//! colour endpoint, log-scaled through the codebook) times `B0`. At load
//! a table of every (endpoint, endpoint, mode) → four decoded values per
//! channel is built, so a block costs three table reads and per channel
//! one permute of its indices and one multiply-add. The vector rows
//! ([`super::x86`], AVX-512 and AVX2 + FMA) take the row's active block
//! columns as a list; the portable loop here is their reference.

use super::palette::{bc1_keys, bc1_palette_bytes, Bc1Table};
use super::rows::{DenseRow, DenseScratch, GatherStats};
#[cfg(target_arch = "x86_64")]
use super::x86;
use radiosity_bakefile::codec::decode::Codebook;

/// A BC1 matrix's decoding tables and the kernel that runs it.
pub(super) struct Bc1Rows {
    tables: [Bc1Table; 3],
    /// "avx512", "avx2" or "none" ([`super::simd_kind`], or "none" when
    /// the vector paths are off).
    vector: &'static str,
}

impl Bc1Rows {
    /// The tables of `book` (the decoded value of each palette entry is
    /// `bcdec_rs`'s rounding of the interpolated byte, through the codec's
    /// log table, as `Encoded::decode` computes it), for the `vector`
    /// kernels.
    pub(super) fn new(book: &Codebook, vector: &'static str) -> Bc1Rows {
        let tables = std::array::from_fn(|c| {
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
        });
        Bc1Rows { tables, vector }
    }

    /// Runs on the AVX2 kernel instead ([`super::CompressedGather::on_avx2`]).
    pub(super) fn set_vector(&mut self, vector: &'static str) {
        self.vector = vector;
    }

    /// Whether the row runs in one vector call over a list of its active
    /// block columns, which reads `B0` by group: on AVX-512 with the 24
    /// accumulators of 8 block rows in registers, so for tiles of at most
    /// 32 rows, the encoder's (larger tiles, which the reader accepts,
    /// take the portable path there); on AVX2 always.
    pub(super) fn vector_row(&self, bh: usize) -> bool {
        self.vector == "avx2" || (self.vector == "avx512" && bh <= 8)
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
        if !self.vector_row(row.bh) {
            return row.each_column(8 * row.bh, stats, |col, b| self.column(col, b, acc));
        }
        row.list_columns(&mut scratch.fast_cols, stats);
        #[cfg(target_arch = "x86_64")]
        {
            let (d, cols, b0p) = (row.dense, &scratch.fast_cols[..], row.inputs.b0p);
            let t = &self.tables;
            if self.vector == "avx2" {
                // SAFETY: `vector` is "avx2" only where `simd_kind` found
                // AVX2 and FMA.
                unsafe { x86::bc1_row_avx2(d, cols, b0p, t, &mut scratch.keys, acc) };
                return;
            }
            let k = &mut scratch.keys512;
            // SAFETY: `vector` is "avx512" only where the CPU reports
            // AVX-512F. The common full row of tiles (8 block rows) with
            // its accumulators in registers; the last, shorter one through
            // the same code with fewer rows.
            unsafe {
                match row.bh {
                    8 => x86::bc1_row_avx512::<8>(d, cols, b0p, t, k, acc),
                    7 => x86::bc1_row_avx512::<7>(d, cols, b0p, t, k, acc),
                    6 => x86::bc1_row_avx512::<6>(d, cols, b0p, t, k, acc),
                    5 => x86::bc1_row_avx512::<5>(d, cols, b0p, t, k, acc),
                    4 => x86::bc1_row_avx512::<4>(d, cols, b0p, t, k, acc),
                    3 => x86::bc1_row_avx512::<3>(d, cols, b0p, t, k, acc),
                    2 => x86::bc1_row_avx512::<2>(d, cols, b0p, t, k, acc),
                    _ => x86::bc1_row_avx512::<1>(d, cols, b0p, t, k, acc),
                }
            }
        }
    }

    /// One BC1 block column (`acc.len()` blocks) times `b`, into `acc`:
    /// the portable path, the vector rows' reference.
    fn column(&self, col: &[u8], b: &[[f32; 4]; 3], acc: &mut [[[f32; 16]; 3]]) {
        for (k, a) in acc.iter_mut().enumerate() {
            let word = u64::from_le_bytes(col[8 * k..8 * k + 8].try_into().expect("8 bytes"));
            let keys = bc1_keys(word);
            let idx = keys[3];
            for ch in 0..3 {
                let pal = &self.tables[ch].values[keys[ch] as usize];
                for (lane, v) in a[ch].iter_mut().enumerate() {
                    let q = (idx >> (2 * lane)) & 3;
                    *v += pal[q as usize] * b[ch][lane & 3];
                }
            }
        }
    }
}
