//! Benchmarks behind `radiosity bench`: every time is printed beside its
//! error against a named reference (here: the f64 CPU reference, measured
//! in the same run), and throughput beside the machine's measured memory
//! bandwidth. Timings on a shared 2-core machine are noisy; compare the
//! ratios within one run.

pub mod accuracy;
pub mod compression;
pub mod form_factor;
pub mod frame;
pub mod frame_gl;
pub mod images;
pub mod probes;
pub mod skips;
pub mod stress;
pub mod svg_plot;
pub mod sweep;
pub mod transfer;
pub mod voxelize;

use std::time::Instant;

/// Host memory bandwidth in bytes/s: the best of a few copies of a 256 MiB
/// buffer (read + write counted), a STREAM-copy-like figure.
pub fn memory_bandwidth() -> f64 {
    let n = 32 << 20; // 32 Mi u64 = 256 MiB
    let src = vec![1u64; n];
    let mut dst = vec![0u64; n];
    let mut best = f64::INFINITY;
    for _ in 0..3 {
        let t = Instant::now();
        dst.copy_from_slice(&src);
        std::hint::black_box(&mut dst);
        best = best.min(t.elapsed().as_secs_f64());
    }
    (2 * n * 8) as f64 / best
}

/// Host memory bandwidth in bytes/s from a STREAM-like triad `a = b + s c`
/// over three arrays of 2^25 f32 (128 MiB each), on all threads (rayon),
/// counting 12 bytes per element (two reads, one write); the best of 5.
pub fn memory_bandwidth_triad() -> f64 {
    use rayon::prelude::*;
    let n = 1usize << 25;
    let b = vec![1.0f32; n];
    let c = vec![2.0f32; n];
    let mut a = vec![0.0f32; n];
    let mut best = f64::INFINITY;
    for _ in 0..5 {
        let t = Instant::now();
        a.par_chunks_mut(1 << 16)
            .zip(b.par_chunks(1 << 16))
            .zip(c.par_chunks(1 << 16))
            .for_each(|((a, b), c)| {
                for i in 0..a.len() {
                    a[i] = b[i] + 3.0 * c[i];
                }
            });
        std::hint::black_box(&mut a);
        best = best.min(t.elapsed().as_secs_f64());
    }
    (12 * n) as f64 / best
}

/// The machine's peak rate of f32 fused multiply-adds, in lane operations
/// per second on all threads (rayon): per thread 12 independent chains of
/// 8-lane FMAs (AVX2 + FMA; enough chains to cover the FMA latency on two
/// pipes), the best of 5. `None` where the CPU has no AVX2 and FMA. The
/// compute roof the gather's multiply-adds are held against, as the triad
/// is the memory roof.
pub fn fma_peak() -> Option<f64> {
    use rayon::prelude::*;
    #[cfg(target_arch = "x86_64")]
    {
        if !(std::arch::is_x86_feature_detected!("avx2")
            && std::arch::is_x86_feature_detected!("fma"))
        {
            return None;
        }
        let threads = rayon::current_num_threads();
        let iters = 4_000_000usize;
        let mut best = f64::INFINITY;
        for _ in 0..5 {
            let t = Instant::now();
            let s: f32 = (0..threads)
                .into_par_iter()
                // SAFETY: AVX2 and FMA checked above.
                .map(|_| unsafe { fma_chains(iters) })
                .sum();
            std::hint::black_box(s);
            best = best.min(t.elapsed().as_secs_f64());
        }
        Some((threads * iters * 12 * 8) as f64 / best)
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        None
    }
}

/// `iters` rounds of 12 independent 8-lane FMAs; returns their sum so that
/// nothing is optimised away.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn fma_chains(iters: usize) -> f32 {
    use std::arch::x86_64::*;
    let a = _mm256_set1_ps(std::hint::black_box(0.999_9));
    let b = _mm256_set1_ps(std::hint::black_box(1e-7));
    let mut acc = [_mm256_set1_ps(1.0); 12];
    for _ in 0..iters {
        for x in acc.iter_mut() {
            *x = _mm256_fmadd_ps(*x, a, b);
        }
    }
    let mut lanes = [0.0f32; 8];
    let mut sum = _mm256_setzero_ps();
    for x in acc {
        sum = _mm256_add_ps(sum, x);
    }
    _mm256_storeu_ps(lanes.as_mut_ptr(), sum);
    lanes.iter().sum()
}

pub fn best_of<T>(
    repeat: usize,
    mut f: impl FnMut() -> anyhow::Result<T>,
) -> anyhow::Result<(T, f64)> {
    let mut best = f64::INFINITY;
    let mut last = None;
    for _ in 0..repeat {
        let t = Instant::now();
        let v = f()?;
        best = best.min(t.elapsed().as_secs_f64());
        last = Some(v);
    }
    Ok((last.expect("repeat >= 1"), best))
}

/// The machine's CPU model from `/proc/cpuinfo`, if readable.
pub fn cpu_model() -> Option<String> {
    let info = std::fs::read_to_string("/proc/cpuinfo").ok()?;
    info.lines()
        .find(|l| l.starts_with("model name"))
        .and_then(|l| l.split_once(':'))
        .map(|(_, m)| m.trim().to_string())
}

/// `args` as one shell command line, each argument single-quoted where it
/// holds characters the shell would interpret, for the report's preamble.
pub fn shell_command_line(args: &[String]) -> String {
    args.iter()
        .map(|a| {
            let plain = !a.is_empty()
                && a.chars()
                    .all(|c| c.is_ascii_alphanumeric() || "_./:=,+-@%".contains(c));
            if plain {
                a.clone()
            } else {
                format!("'{}'", a.replace('\'', r"'\''"))
            }
        })
        .collect::<Vec<_>>()
        .join(" ")
}

/// Creates a report's directory `out` and a fresh temporary directory for
/// its bakes (`radiosity-<tag>-<pid>`), returned.
pub(crate) fn report_dirs(out: &std::path::Path, tag: &str) -> anyhow::Result<std::path::PathBuf> {
    use anyhow::Context;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let bakes = std::env::temp_dir().join(format!("radiosity-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&bakes).with_context(|| format!("creating {}", bakes.display()))?;
    Ok(bakes)
}

/// The fastest of `repeat` runs: its value and its time.
pub fn best<T>(repeat: usize, mut f: impl FnMut() -> T) -> (T, f64) {
    let mut best: Option<(T, f64)> = None;
    for _ in 0..repeat.max(1) {
        keep_fastest(&mut best, &mut f);
    }
    best.expect("at least one run")
}

/// Runs `f` once; keeps its value and time in `best` when it is faster.
pub(crate) fn keep_fastest<T>(best: &mut Option<(T, f64)>, f: impl FnOnce() -> T) {
    let t = Instant::now();
    let v = f();
    let s = t.elapsed().as_secs_f64();
    if best.as_ref().is_none_or(|b| s < b.1) {
        *best = Some((v, s));
    }
}

/// Relative RMS difference of `a` against `r`, three channels pooled.
pub fn rel_rms(a: &[Vec<f32>; 3], r: &[Vec<f64>; 3]) -> f64 {
    let (mut d, mut s) = (0.0, 0.0);
    for c in 0..3 {
        for (x, y) in a[c].iter().zip(&r[c]) {
            d += (*x as f64 - y) * (*x as f64 - y);
            s += y * y;
        }
    }
    if s > 0.0 {
        (d / s).sqrt()
    } else {
        0.0
    }
}
