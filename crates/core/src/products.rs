//! Sums of products for many samples at once, the inner loop of the codec
//! choice's measures (the bake's exact `T B0` and the bake file's
//! many-sample gather): `acc[q] += x_c · b_c[q]` along a run of columns
//! `c`, for a block of samples `q` whose accumulators stay in registers for
//! the whole run. Each accumulator adds its terms in column order, one
//! rounded product and one rounded sum at a time (Rust never fuses them),
//! so the result is the same, bit for bit, as the plain loop's, with or
//! without the wider instructions picked at run time.

/// A sum of products of f32 values: f32 or f64 (each product of two f32
/// widened to f64 is exact).
pub trait Accumulator:
    Copy + Default + Send + Sync + std::ops::AddAssign + std::ops::Mul<Output = Self> + From<f32>
{
}

impl<A> Accumulator for A where
    A: Copy + Default + Send + Sync + std::ops::AddAssign + std::ops::Mul<Output = A> + From<f32>
{
}

/// Samples whose accumulators [`add_products`] keeps in registers: 32
/// took 0.51 × the time of one multiply-add per sample and column, loaded
/// and stored, in the gather of 64 samples through the BC1 encoding of a
/// synthetic banded 4,096² matrix (AVX2, this machine; 16: 0.61 ×; SSE2
/// only, 16: 0.83 ×).
pub const SAMPLE_BLOCK: usize = 32;

/// A run of columns along one row: the row's value of column `c` is
/// `x[c · stride_x]`, the column's samples start at `b[c · stride_b]`.
#[derive(Clone, Copy, Debug)]
pub struct Run<'a> {
    pub x: &'a [f32],
    pub stride_x: usize,
    pub b: &'a [f32],
    pub stride_b: usize,
    pub cols: usize,
}

/// `acc[q] += x[c · stride_x] · b[c · stride_b + q]` for every sample `q`
/// of `acc` (any length) and column `c` of the run, in column order per
/// sample. Blocks of [`SAMPLE_BLOCK`] samples run with their accumulators
/// in registers, on AVX2 where the processor has it.
pub fn add_products<A: Accumulator>(acc: &mut [A], run: Run) {
    if run.cols == 0 {
        return;
    }
    assert!(
        run.x.len() > (run.cols - 1) * run.stride_x,
        "x holds every column's value"
    );
    assert!(
        run.b.len() >= (run.cols - 1) * run.stride_b + acc.len(),
        "b holds every column's samples"
    );
    let mut q = 0;
    while q < acc.len() {
        let len = SAMPLE_BLOCK.min(acc.len() - q);
        let from = |s: usize| Run {
            b: &run.b[s..],
            ..run
        };
        if len == SAMPLE_BLOCK {
            block_dispatch::<A, SAMPLE_BLOCK>(&mut acc[q..q + len], from(q));
        } else {
            for (s, a) in acc[q..].iter_mut().enumerate() {
                block::<A, 1>(std::slice::from_mut(a), from(q + s));
            }
        }
        q += len;
    }
}

/// [`block`] with AVX2 where the processor has it.
#[inline(always)]
fn block_dispatch<A: Accumulator, const S: usize>(acc: &mut [A], run: Run) {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the processor has AVX2 (checked just above), the one
            // requirement of `block_avx2`.
            unsafe { block_avx2::<A, S>(acc, run) };
            return;
        }
    }
    block::<A, S>(acc, run)
}

/// [`block`] compiled for AVX2: four f64 (eight f32) per instruction.
///
/// # Safety
/// The processor must have AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn block_avx2<A: Accumulator, const S: usize>(acc: &mut [A], run: Run) {
    block::<A, S>(acc, run)
}

/// `S` samples along the run, their sums held in a local array (registers)
/// and stored once at the end.
#[inline(always)]
fn block<A: Accumulator, const S: usize>(acc: &mut [A], run: Run) {
    let mut sum: [A; S] = std::array::from_fn(|q| acc[q]);
    for c in 0..run.cols {
        let xc = A::from(run.x[c * run.stride_x]);
        let bc = &run.b[c * run.stride_b..c * run.stride_b + S];
        for q in 0..S {
            sum[q] += xc * A::from(bc[q]);
        }
    }
    acc[..S].copy_from_slice(&sum);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The plain loop: one multiply-add per sample and column, in column
    /// order.
    fn plain<A: Accumulator>(acc: &mut [A], run: Run) {
        for c in 0..run.cols {
            for (q, a) in acc.iter_mut().enumerate() {
                *a += A::from(run.x[c * run.stride_x]) * A::from(run.b[c * run.stride_b + q]);
            }
        }
    }

    #[test]
    fn the_blocks_equal_the_plain_loop_bit_for_bit() {
        let mut s = 0x2545_f491_4f6c_dd1du64;
        let mut rnd = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            // Values over many octaves, some exact zeros.
            let u = (s >> 11) as f64 / (1u64 << 53) as f64;
            if u < 0.1 {
                0.0
            } else {
                (u * 40.0 - 20.0).exp2() as f32
            }
        };
        // Sample counts around the block size, with remainders; runs of
        // columns as in a tile and as in a whole row.
        for samples in [1usize, 7, 31, 32, 33, 64, 65, 100] {
            for (cols, stride_x) in [(1usize, 1usize), (5, 3), (32, 3), (300, 1)] {
                let stride_b = samples + 3;
                let x: Vec<f32> = (0..cols * stride_x).map(|_| rnd()).collect();
                let b: Vec<f32> = (0..cols * stride_b).map(|_| rnd()).collect();
                let start: Vec<f64> = (0..samples).map(|_| rnd() as f64).collect();
                let run = Run {
                    x: &x,
                    stride_x,
                    b: &b,
                    stride_b,
                    cols,
                };
                let (mut got, mut want) = (start.clone(), start.clone());
                add_products(&mut got, run);
                plain(&mut want, run);
                let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&got), bits(&want), "{samples} samples, {cols} columns");
                let mut got32: Vec<f32> = start.iter().map(|&v| v as f32).collect();
                let mut want32 = got32.clone();
                add_products(&mut got32, run);
                plain(&mut want32, run);
                assert_eq!(
                    got32.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
                    want32.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
                );
            }
        }
    }

    #[test]
    fn no_columns_change_nothing() {
        let mut acc = vec![1.5f64; 40];
        let run = Run {
            x: &[],
            stride_x: 1,
            b: &[],
            stride_b: 40,
            cols: 0,
        };
        add_products(&mut acc, run);
        assert!(acc.iter().all(|&a| a == 1.5));
    }
}
