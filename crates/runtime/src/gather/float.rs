//! The gather's float formats: f16, f32 and BC6H (half-float blocks), the
//! codecs a bake chooses when BC1 and BC4 cannot reach the error asked for.
//!
//! At load every stored tile is re-laid by block column (4 matrix columns,
//! one group of `B0`), block row after block row, as the BC1 tiles are, so
//! that a skipped column group skips its memory and, for BC6H, its
//! decoding: an f16 or f32 block is its stored channels one after the other,
//! each 16 values row by row (a 4 × 4 block of the matrix), a BC6H block its
//! unpacked form ([`bc6h::UNPACKED_BYTES`] bytes). The kernels add a block column times its 4 values of `B0` into
//! the row of tiles' accumulators (per block row and output channel, lane
//! `4 r + c` for row `r`, column `c` of the block), which the caller sums
//! per row as it does for BC1.
//!
//! f16 and f32 are one load (f16: one conversion, F16C on x86) and one
//! multiply and add per 16 values on AVX-512, two on AVX2, so they run at
//! the memory's speed; the portable loop is their reference in the tests
//! (the same operations: no fused multiply-add, so the same bits). BC6H
//! blocks are unpacked at load and decoded per block column by [`bc6h`].
//! The f16 and BC6H scale, a power of two, is folded into `B0` by the
//! caller (exact).

use super::bc6h;
use super::rows::{DenseRow, GatherStats};
use half::f16;
use radiosity_bakefile::codec::DenseFormat;

/// A float matrix (f16, f32 or BC6H) as the gather runs it.
pub(super) struct FloatRows {
    format: DenseFormat,
    channels: usize,
    /// The stored scale's inverse per channel (1 for f32): a power of two.
    inv_scale: [f32; 3],
    kernel: FloatKernel,
}

impl FloatRows {
    /// A matrix of `format` with `channels` stored channels, scaled by
    /// `1 / inv_scale`, run by the kernel for `vector`.
    pub(super) fn new(
        format: DenseFormat,
        channels: usize,
        inv_scale: [f32; 3],
        vector: &str,
    ) -> FloatRows {
        FloatRows {
            format,
            channels,
            inv_scale,
            kernel: FloatKernel::for_cpu(vector),
        }
    }

    /// Runs on the kernel for `vector` instead.
    pub(super) fn set_vector(&mut self, vector: &str) {
        self.kernel = FloatKernel::for_cpu(vector);
    }

    /// `row`'s active block columns times `B0` into `acc` (per block row
    /// and output channel, 16 lanes; an f16 or f32 tile may end in a
    /// partial block, padded with zeros at load).
    pub(super) fn row(&self, row: &DenseRow, acc: &mut [[[f32; 16]; 3]], stats: &mut GatherStats) {
        let (f, c, out_ch) = (self.format, self.channels, row.inputs.out_ch);
        let col_bytes = column_bytes(f, row.bh, c);
        row.each_column(col_bytes, stats, |col, b| {
            // The stored scale (1 for f32) into B0: a power of two, so
            // exact.
            let mut b = *b;
            if f != DenseFormat::F32 {
                for (oc, bc) in b.iter_mut().enumerate().take(out_ch) {
                    let s = self.inv_scale[oc.min(c - 1)];
                    bc.iter_mut().for_each(|v| *v *= s);
                }
            }
            column(self.kernel, f, col, c, &b, out_ch, acc);
        });
    }
}

/// Bytes of one stored value.
fn value_bytes(format: DenseFormat) -> usize {
    match format {
        DenseFormat::F16 => 2,
        _ => 4,
    }
}

/// Bytes of one re-laid block column of `bh` block rows.
fn column_bytes(format: DenseFormat, bh: usize, channels: usize) -> usize {
    match format {
        DenseFormat::Bc6h => bc6h::UNPACKED_BYTES * bh,
        _ => 16 * channels * value_bytes(format) * bh,
    }
}

/// Appends tile `src` (`h × w` entries as the file stores it: f16 and f32
/// row-major with the channels side by side, BC6H blocks row by row)
/// re-laid by block column (module doc) to `out`. An f16 or f32 tile's
/// size need not be a multiple of 4 (their image is `n` wide): its last
/// blocks are padded with zeros, which add `0 · B0 = 0` (and past `n`, `B0`
/// is 0 too).
pub(super) fn relay_tile(
    format: DenseFormat,
    src: &[u8],
    h: usize,
    w: usize,
    channels: usize,
    out: &mut Vec<u8>,
) {
    let (bh, bw) = (h.div_ceil(4), w.div_ceil(4));
    if format == DenseFormat::Bc6h {
        for bc in 0..bw {
            for br in 0..bh {
                let k = br * bw + bc;
                bc6h::unpack(src[16 * k..16 * k + 16].try_into().expect("16 bytes"), out);
            }
        }
        return;
    }
    let es = value_bytes(format);
    for bc in 0..bw {
        for br in 0..bh {
            for c in 0..channels {
                for r in 4 * br..4 * br + 4 {
                    for x in 4 * bc..4 * bc + 4 {
                        if r < h && x < w {
                            let at = ((r * w + x) * channels + c) * es;
                            out.extend_from_slice(&src[at..at + es]);
                        } else {
                            out.extend(std::iter::repeat_n(0u8, es));
                        }
                    }
                }
            }
        }
    }
}

/// Which code runs a float block column.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum FloatKernel {
    Portable,
    #[cfg(target_arch = "x86_64")]
    Avx512,
    #[cfg(target_arch = "x86_64")]
    Avx2,
}

impl FloatKernel {
    /// The vector kernel for `vector` ([`super::simd_kind`]), where the CPU
    /// also converts halves (F16C; AVX-512F includes its 512-bit form).
    fn for_cpu(vector: &str) -> FloatKernel {
        #[cfg(target_arch = "x86_64")]
        {
            if vector == "avx512" {
                return FloatKernel::Avx512;
            }
            if vector == "avx2" && std::arch::is_x86_feature_detected!("f16c") {
                return FloatKernel::Avx2;
            }
        }
        let _ = vector;
        FloatKernel::Portable
    }
}

/// One re-laid block column `col` (`acc.len()` block rows, `channels`
/// stored) times `b` (its 4 columns of `B0` per output channel, the
/// format's scale folded in) into the first `out_ch` channels of `acc`.
fn column(
    kernel: FloatKernel,
    format: DenseFormat,
    col: &[u8],
    channels: usize,
    b: &[[f32; 4]; 3],
    out_ch: usize,
    acc: &mut [[[f32; 16]; 3]],
) {
    assert!(col.len() >= column_bytes(format, acc.len(), channels));
    if format == DenseFormat::Bc6h {
        // Three stored channels, so three output channels.
        debug_assert_eq!(out_ch, 3);
        return match kernel {
            // SAFETY: the kernel was chosen for what this CPU reported.
            #[cfg(target_arch = "x86_64")]
            FloatKernel::Avx512 => unsafe { bc6h::column_avx512(col, b, acc) },
            // SAFETY: as above.
            #[cfg(target_arch = "x86_64")]
            FloatKernel::Avx2 => unsafe { bc6h::column_avx2(col, b, acc) },
            FloatKernel::Portable => bc6h::column(col, b, acc),
        };
    }
    let half = format == DenseFormat::F16;
    match kernel {
        // SAFETY: the kernel was chosen for what this CPU reported, and
        // `col` holds every block the kernel reads (asserted above).
        #[cfg(target_arch = "x86_64")]
        FloatKernel::Avx512 => unsafe { plain_column_avx512(half, col, channels, b, out_ch, acc) },
        // SAFETY: as above (AVX2 and F16C).
        #[cfg(target_arch = "x86_64")]
        FloatKernel::Avx2 => unsafe { plain_column_avx2(half, col, channels, b, out_ch, acc) },
        FloatKernel::Portable => plain_column(half, col, channels, b, out_ch, acc),
    }
}

/// An f16 (`half`) or f32 block column, portable: the reference of the
/// vector kernels.
fn plain_column(
    half: bool,
    col: &[u8],
    channels: usize,
    b: &[[f32; 4]; 3],
    out_ch: usize,
    acc: &mut [[[f32; 16]; 3]],
) {
    let es = if half { 2 } else { 4 };
    let mut v = [0.0f32; 16];
    for (br, a) in acc.iter_mut().enumerate() {
        for (oc, (a, b)) in a.iter_mut().zip(b).enumerate().take(out_ch) {
            let at = (br * channels + oc.min(channels - 1)) * 16 * es;
            let bytes = &col[at..at + 16 * es];
            for (x, q) in v.iter_mut().zip(bytes.chunks_exact(es)) {
                *x = if half {
                    f16::from_le_bytes([q[0], q[1]]).to_f32()
                } else {
                    f32::from_le_bytes([q[0], q[1], q[2], q[3]])
                };
            }
            for (lane, (s, x)) in a.iter_mut().zip(&v).enumerate() {
                *s += x * b[lane & 3];
            }
        }
    }
}

/// [`plain_column`] on AVX-512: per block row and output channel one load
/// of 16 values (f16: converted by `vcvtph2ps`), a multiply and an add
/// into the accumulator (not fused, as in the portable loop: the same
/// bits; the extra instruction does not show, the loop being bound by
/// memory or by the conversions).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn plain_column_avx512(
    half: bool,
    col: &[u8],
    channels: usize,
    b: &[[f32; 4]; 3],
    out_ch: usize,
    acc: &mut [[[f32; 16]; 3]],
) {
    use std::arch::x86_64::*;
    let es = if half { 2 } else { 4 };
    let bv: [__m512; 3] =
        std::array::from_fn(|oc| _mm512_broadcast_f32x4(_mm_loadu_ps(b[oc].as_ptr())));
    let p = col.as_ptr();
    for (br, a) in acc.iter_mut().enumerate() {
        for oc in 0..out_ch {
            let at = p.add((br * channels + oc.min(channels - 1)) * 16 * es);
            let v = if half {
                _mm512_cvtph_ps(_mm256_loadu_si256(at as *const __m256i))
            } else {
                _mm512_loadu_ps(at as *const f32)
            };
            let s = a[oc].as_mut_ptr();
            _mm512_storeu_ps(
                s,
                _mm512_add_ps(_mm512_loadu_ps(s), _mm512_mul_ps(v, bv[oc])),
            );
        }
    }
}

/// [`plain_column_avx512`] in 8-lane halves (a block's rows 0–1 and 2–3).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,f16c")]
unsafe fn plain_column_avx2(
    half: bool,
    col: &[u8],
    channels: usize,
    b: &[[f32; 4]; 3],
    out_ch: usize,
    acc: &mut [[[f32; 16]; 3]],
) {
    use std::arch::x86_64::*;
    let es = if half { 2 } else { 4 };
    // The 4 values in both 128-bit halves (an unaligned load: `b` is only
    // f32-aligned).
    let bv: [__m256; 3] = std::array::from_fn(|oc| {
        let x = _mm_loadu_ps(b[oc].as_ptr());
        _mm256_set_m128(x, x)
    });
    let p = col.as_ptr();
    for (br, a) in acc.iter_mut().enumerate() {
        for oc in 0..out_ch {
            let at = p.add((br * channels + oc.min(channels - 1)) * 16 * es);
            for part in 0..2 {
                let v = if half {
                    _mm256_cvtph_ps(_mm_loadu_si128(at.add(16 * part) as *const __m128i))
                } else {
                    _mm256_loadu_ps((at as *const f32).add(8 * part))
                };
                let s = a[oc].as_mut_ptr().add(8 * part);
                _mm256_storeu_ps(
                    s,
                    _mm256_add_ps(_mm256_loadu_ps(s), _mm256_mul_ps(v, bv[oc])),
                );
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every f16 and f32 kernel this CPU runs gives the portable loop's
    /// bits (the same operations, no fused multiply-add), for one and
    /// three stored channels into one and three output channels, on
    /// values spread over the halves' range, subnormals included.
    #[test]
    fn the_vector_kernels_give_the_portable_bits() {
        let mut rng = radiosity_core::math::SplitMix64::new(9);
        let mut kernels = vec![FloatKernel::Portable];
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx512f") {
                kernels.push(FloatKernel::Avx512);
            }
            if std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("f16c")
            {
                kernels.push(FloatKernel::Avx2);
            }
        }
        let mut tested = 0;
        for format in [DenseFormat::F16, DenseFormat::F32] {
            for (channels, out_ch) in [(1, 1), (1, 3), (3, 3)] {
                for bh in [1, 3, 8] {
                    let n = 16 * channels * bh;
                    let values: Vec<f32> = (0..n)
                        .map(|_| (10f64.powf(-9.0 + 13.0 * rng.uniform())) as f32)
                        .collect();
                    let col: Vec<u8> = values
                        .iter()
                        .flat_map(|&v| match format {
                            DenseFormat::F16 => f16::from_f32(v).to_le_bytes().to_vec(),
                            _ => v.to_le_bytes().to_vec(),
                        })
                        .collect();
                    let b: [[f32; 4]; 3] =
                        std::array::from_fn(|_| std::array::from_fn(|_| rng.uniform() as f32));
                    let start: Vec<[[f32; 16]; 3]> = (0..bh)
                        .map(|_| {
                            std::array::from_fn(|_| std::array::from_fn(|_| rng.uniform() as f32))
                        })
                        .collect();
                    let run = |k: FloatKernel| {
                        let mut acc = start.clone();
                        column(k, format, &col, channels, &b, out_ch, &mut acc);
                        acc.iter()
                            .flat_map(|a| a.iter().flatten().map(|v| v.to_bits()))
                            .collect::<Vec<u32>>()
                    };
                    let want = run(FloatKernel::Portable);
                    for &k in &kernels {
                        assert_eq!(
                            run(k),
                            want,
                            "{format:?}, {channels} → {out_ch}, {bh} rows, {k:?}"
                        );
                        tested += 1;
                    }
                }
            }
        }
        assert!(tested >= 18);
    }
}
