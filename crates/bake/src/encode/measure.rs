//! Error measures of a compressed matrix (docs/design.md section 3, measure 3)
//! and the choice of the cheapest codec setting under an error bound.

use super::prepared::Prepared;
use super::{encode_prepared, sparse_count, EncodeError};
use radiosity_bakefile::codec::{CodecKind, Encoded, SparseValues, LOG_RANGE_AUTO};
use radiosity_core::products::{add_products, Run};
use rayon::prelude::*;
use serde::Serialize;

/// Rows of tiles ([`radiosity_bakefile::codec::TILE`] rows each) that the
/// choice's estimate encodes and gathers at least: 1 row of tiles in
/// `stride = ⌊tiles / 48⌋` ([`estimate_stride`]).
pub const ESTIMATE_TILE_ROWS: usize = 48;

/// The smallest stride the estimate is made at. A sampled candidate pays
/// 1/stride of the tiles and gathers and its selection pass over the whole
/// matrix, and one that goes on to the full measure pays both: on Sponza
/// at 3,938 patches and stride 2 (when each candidate also made the shared
/// passes, since made once per matrix by `Prepared`), a rejection took
/// 1.5 s against 2.9 s for a full measure and a candidate measured both
/// ways 4.4 s, so the encode stage was no faster (24.4 s against 23.8 s
/// without the estimate, one run). At stride 2 a rejection still saves
/// about half a full measure and a pass-through costs half of one more;
/// from stride 4 (above 6,112 patches) a rejection saves three quarters
/// and a pass-through costs a quarter.
pub const ESTIMATE_MIN_STRIDE: usize = 4;

/// The most a candidate's estimated `H` error may exceed the bound and
/// still go on to the full measure: the estimate is rejected on when it is
/// above the bound by more than its margin ([`Estimate::margin`]), which
/// lies between [`ESTIMATE_MIN_MARGIN`] and this. The estimate is the same
/// relative RMS over 1 row of tiles in `stride`: over the 18 default
/// candidates on the synthetic room at stride 4 it stayed within
/// 0.78–1.06 of the full measure (`tests/codec.rs`, which holds every
/// candidate under its margin), on Sponza at 3,938 patches (stride 2)
/// within 0.91–0.93 for the 4 candidates measured both ways after the
/// greedy reordering and 1.08–1.11 for the 4 after the Hilbert one, and at
/// 12,503 patches (stride 8, the bake's own) within 0.95–1.10. A wrong
/// rejection would only cost bytes (a dearer setting chosen), never the
/// bound: only the full measure accepts. The bake's progress lines print
/// the estimate beside each full measure, a running check on every scene.
pub const ESTIMATE_MARGIN: f64 = 1.5;

/// The least margin of an estimate ([`Estimate::margin`]), however small
/// its standard error: what the sampling error does not show, the log
/// formats' mass correction taken over the sampled tiles instead of all
/// ([`encode_sampled`](super::encode_sampled)) and the rows of tiles taken in a fixed stride
/// rather than at random; on Sponza at 12,503 patches the estimate was up
/// to 1.10 × the full measure.
pub const ESTIMATE_MIN_MARGIN: f64 = 1.15;

/// Standard errors an estimate must clear the bound by to reject
/// ([`Estimate::margin`]): 3, a one-sided 0.13 % chance under a normal
/// error.
pub const ESTIMATE_STANDARD_ERRORS: f64 = 3.0;

/// A candidate's `H` error estimated over 1 row of tiles in `stride`
/// ([`h_error_estimate`]), with its standard error.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Estimate {
    /// The relative RMS error over the sampled rows.
    pub error: f64,
    /// Its standard error, from the spread of the sampled rows of tiles
    /// (module doc of [`h_error_estimate`]); 0 when every row is sampled.
    pub std_error: f64,
    /// The rows of tiles sampled.
    pub rows: usize,
}

impl Estimate {
    /// How far above the bound the estimate must be to reject its
    /// candidate: `1 + 3 σ / error` ([`ESTIMATE_STANDARD_ERRORS`]), at
    /// least [`ESTIMATE_MIN_MARGIN`] and at most [`ESTIMATE_MARGIN`].
    pub fn margin(&self) -> f64 {
        let spread = if self.error > 0.0 {
            1.0 + ESTIMATE_STANDARD_ERRORS * self.std_error / self.error
        } else {
            ESTIMATE_MARGIN
        };
        spread.clamp(ESTIMATE_MIN_MARGIN, ESTIMATE_MARGIN)
    }

    /// Whether the estimate rejects a candidate under `max_error`.
    pub fn rejects(&self, max_error: f64) -> bool {
        self.error > self.margin() * max_error
    }
}

/// The estimate's row stride for `n` patches: `⌊tiles / 48⌋`, or 1 (no
/// estimate, every candidate measured in full) below
/// [`ESTIMATE_MIN_STRIDE`].
pub fn estimate_stride(n: usize) -> usize {
    let stride = n.div_ceil(radiosity_bakefile::codec::TILE) / ESTIMATE_TILE_ROWS;
    if stride >= ESTIMATE_MIN_STRIDE {
        stride
    } else {
        1
    }
}

/// How a candidate's `H` error was found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Measured {
    /// Over every patch ([`h_error`]); `estimate`: the estimate that let it
    /// through to the full measure, where one was made (a running check of
    /// the estimate and its margin, shown in the bake's progress lines).
    Full { estimate: Option<Estimate> },
    /// Estimated over every `stride`-th row of tiles ([`h_error_estimate`])
    /// and far enough above the bound to reject the candidate, by more than
    /// `margin` times it ([`Estimate::margin`]).
    Estimated { stride: usize, margin: f64 },
}

impl Measured {
    /// Whether the error was measured over every patch.
    pub fn is_full(self) -> bool {
        matches!(self, Measured::Full { .. })
    }
}

/// Why no codec setting could be chosen.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ChooseError {
    #[error("the error bound must be a non-negative number, got {0}")]
    MaxError(f64),
    #[error("choosing a codec by error needs at least one B0 sample")]
    NoSamples,
    #[error("every B0 sample needs {0} values per channel")]
    SampleSize(usize),
    #[error("no codec reaches a relative H error of {max_error}; tried {tried}")]
    NoCandidate { max_error: f64, tried: String },
    #[error(transparent)]
    Encode(#[from] EncodeError),
}

/// Errors of a decoded matrix against the original (docs/design.md section 3,
/// measure 3). Entry errors are over all `3 n²` entries (three channels).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct CodecError {
    /// The thesis's table: mean, max and total absolute error per entry.
    pub mean_abs: f64,
    pub max_abs: f64,
    pub total_abs: f64,
    /// `‖T̃ − T‖_F / ‖T‖_F`, the three channels pooled.
    pub rel_frobenius: f64,
    /// `‖H̃ − H‖ / ‖H‖` with `H = T B0`, pooled over all samples, channels
    /// and patches (0 without samples).
    pub rel_rms_h: f64,
    /// The worst single sample's `‖H̃ − H‖ / ‖H‖` (three channels).
    pub max_rel_h: f64,
    /// Entries exactly 0 in `T` but not in `T̃`.
    pub zeros_changed: u64,
    pub samples: usize,
}

impl std::fmt::Display for CodecError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "entry error mean {:.3e} max {:.3e} total {:.3e}; rel. Frobenius {:.3e}; \
             H rel. RMS {:.3e} (worst sample {:.3e}, {} samples); zeros changed {}",
            self.mean_abs,
            self.max_abs,
            self.total_abs,
            self.rel_frobenius,
            self.rel_rms_h,
            self.max_rel_h,
            self.samples,
            self.zeros_changed
        )
    }
}

/// Measures `decoded` against `t` (module doc, [`CodecError`]); products in
/// f64.
pub fn measure(
    t: [&[f32]; 3],
    n: usize,
    decoded: &[Vec<f32>; 3],
    b0_samples: &[[Vec<f32>; 3]],
) -> CodecError {
    #[derive(Default, Clone, Copy)]
    struct Acc {
        sum: f64,
        max: f64,
        diff2: f64,
        ref2: f64,
        zeros: u64,
    }
    let acc = (0..3)
        .flat_map(|c| (0..n).map(move |i| (c, i)))
        .collect::<Vec<_>>()
        .into_par_iter()
        .map(|(c, i)| {
            let mut a = Acc::default();
            let (r, d) = (&t[c][i * n..(i + 1) * n], &decoded[c][i * n..(i + 1) * n]);
            for (&x, &y) in r.iter().zip(d) {
                let e = (y as f64 - x as f64).abs();
                a.sum += e;
                a.max = a.max.max(e);
                a.diff2 += e * e;
                a.ref2 += (x as f64) * (x as f64);
                a.zeros += u64::from(x == 0.0 && y != 0.0);
            }
            a
        })
        .reduce(Acc::default, |a, b| Acc {
            sum: a.sum + b.sum,
            max: a.max.max(b.max),
            diff2: a.diff2 + b.diff2,
            ref2: a.ref2 + b.ref2,
            zeros: a.zeros + b.zeros,
        });
    let entries = (3 * n * n).max(1) as f64;
    let (mut d2, mut r2, mut worst) = (0.0f64, 0.0f64, 0.0f64);
    for b0 in b0_samples {
        let (mut sd, mut sr) = (0.0f64, 0.0f64);
        for c in 0..3 {
            let (x, y) = (mat_vec(t[c], n, &b0[c]), mat_vec(&decoded[c], n, &b0[c]));
            for (a, b) in x.iter().zip(&y) {
                sd += (b - a) * (b - a);
                sr += a * a;
            }
        }
        d2 += sd;
        r2 += sr;
        worst = worst.max(ratio(sd.sqrt(), sr.sqrt()));
    }
    CodecError {
        mean_abs: acc.sum / entries,
        max_abs: acc.max,
        total_abs: acc.sum,
        rel_frobenius: ratio(acc.diff2.sqrt(), acc.ref2.sqrt()),
        rel_rms_h: ratio(d2.sqrt(), r2.sqrt()),
        max_rel_h: worst,
        zeros_changed: acc.zeros,
        samples: b0_samples.len(),
    }
}

/// `a / b`, 0 when both are 0, infinite when only `b` is.
fn ratio(a: f64, b: f64) -> f64 {
    if b > 0.0 {
        a / b
    } else if a > 0.0 {
        f64::INFINITY
    } else {
        0.0
    }
}

/// `M v` in f64 for a row-major n × n f32 matrix.
pub fn mat_vec(m: &[f32], n: usize, v: &[f32]) -> Vec<f64> {
    assert_eq!(v.len(), n);
    (0..n)
        .into_par_iter()
        .map(|i| {
            m[i * n..(i + 1) * n]
                .iter()
                .zip(v)
                .map(|(&a, &b)| a as f64 * b as f64)
                .sum()
        })
        .collect()
}

/// The exact `H = T B0` of every sample and channel (f64), as
/// [`mat_vec`] per sample and channel gives it, the same products summed
/// in the same order, but each row of `T` read once for all samples: `B0`
/// is laid out `[column][sample]` (f32, widened to f64 where it is
/// multiplied, exactly) and each row's sums run along the row a block of
/// samples at a time ([`add_products`]). (The one difference from
/// [`mat_vec`] is the sign of an exact zero sum, which no error measure
/// sees.) Each of the 3 channels streams its matrix once instead of once
/// per sample: 64 error lights read `T` 64 times less.
pub fn exact_products(t: [&[f32]; 3], n: usize, samples: &[[Vec<f32>; 3]]) -> Vec<[Vec<f64>; 3]> {
    let k = samples.len();
    if k == 0 {
        return Vec::new();
    }
    let per_channel: Vec<Vec<f64>> = (0..3)
        .map(|c| {
            let mut vt = vec![0.0f32; n * k];
            for (si, b) in samples.iter().enumerate() {
                assert_eq!(b[c].len(), n);
                for (j, &x) in b[c].iter().enumerate() {
                    vt[j * k + si] = x;
                }
            }
            // Row-major n × k: row i's k products.
            let mut out = vec![0.0f64; n * k];
            out.par_chunks_mut(k).enumerate().for_each(|(i, acc)| {
                let run = Run {
                    x: &t[c][i * n..(i + 1) * n],
                    stride_x: 1,
                    b: &vt,
                    stride_b: k,
                    cols: n,
                };
                add_products(acc, run);
            });
            out
        })
        .collect();
    (0..k)
        .map(|si| std::array::from_fn(|c| (0..n).map(|i| per_channel[c][i * k + si]).collect()))
        .collect()
}

/// The candidates [`choose`] tries by default: BC1-log with the automatic
/// log range and RGB9E5 sparse values at top fractions {0, 0.01, 0.02,
/// 0.03, 0.04, 0.06, 0.08, 0.12, 0.16, 0.2, 0.24}, the same at the top
/// 4 % with f16 and f32 sparse values, the thesis's setting, BC4-log at
/// {0, 0.02}, BC6H, F16 and F32 (exact, so some candidate always passes).
pub fn default_candidates() -> Vec<CodecKind> {
    let bc1 = |top_fraction, sparse| CodecKind::Bc1Log {
        top_fraction,
        log_range: LOG_RANGE_AUTO,
        sparse,
    };
    let mut v: Vec<CodecKind> = [
        0.0, 0.01, 0.02, 0.03, 0.04, 0.06, 0.08, 0.12, 0.16, 0.2, 0.24,
    ]
    .iter()
    .map(|&f| bc1(f, SparseValues::Rgb9e5))
    .collect();
    v.push(bc1(0.04, SparseValues::F16));
    v.push(bc1(0.04, SparseValues::F32));
    v.push(CodecKind::THESIS);
    for &top_fraction in &[0.0, 0.02] {
        v.push(CodecKind::Bc4Log {
            top_fraction,
            log_range: LOG_RANGE_AUTO,
            sparse: SparseValues::Rgb9e5,
        });
    }
    v.extend([CodecKind::Bc6h, CodecKind::F16, CodecKind::F32]);
    v
}

/// How much larger than the smallest passing setting a log-scaled block
/// setting (BC1, BC4) may be and still be chosen over it ([`choose`]).
/// The CPU gathers BC1 faster per frame than BC6H, which stores about
/// twice its bytes, and than f16, about ten times (`radiosity bench
/// frame`, the Cornell box at 3,940 patches, every column: BC1 at 0.57
/// B/entry 1.1 ms, BC6H at 1.0 B/entry 10.1 ms, f16 3.9 ms), and a GPU
/// decodes all of them in hardware: a little more memory buys a faster
/// frame where the CPU gathers.
pub const BLOCK_CODEC_SLACK: f64 = 2.0;

/// The setting [`choose`] takes among `candidates` (empty: the
/// [`default_candidates`]) whose relative RMS error of `H = T̃ · B0` over
/// `b0_samples` is at most `max_error`: the cheapest in total bytes, unless
/// a BC1 or BC4 setting passes within [`BLOCK_CODEC_SLACK`] times its bytes,
/// in which case the cheapest such block setting. Every candidate that can
/// still matter is encoded and measured; ties go to the earlier candidate.
/// Returns the setting, its encoding and its measured error.
pub fn choose(
    t: [&[f32]; 3],
    n: usize,
    b0_samples: &[[Vec<f32>; 3]],
    max_error: f64,
    candidates: &[CodecKind],
) -> Result<(CodecKind, Encoded, f64), ChooseError> {
    choose_with(
        t,
        n,
        b0_samples,
        max_error,
        candidates,
        estimate_stride(n),
        &mut |_, _, _, _| {},
    )
}

/// [`choose`], calling `on_candidate(setting, H error, bytes per entry,
/// how the error was found)` as each candidate is measured (for progress
/// output and reports). Candidates far above the bound are rejected on an
/// estimate over 1 row of tiles in `stride`, by a margin from its own
/// standard error ([`Estimate::rejects`]; the bake passes
/// [`estimate_stride`], 1 measures every candidate in full).
pub fn choose_with(
    t: [&[f32]; 3],
    n: usize,
    b0_samples: &[[Vec<f32>; 3]],
    max_error: f64,
    candidates: &[CodecKind],
    stride: usize,
    on_candidate: &mut dyn FnMut(CodecKind, f64, f64, Measured),
) -> Result<(CodecKind, Encoded, f64), ChooseError> {
    if !(max_error >= 0.0) {
        return Err(ChooseError::MaxError(max_error));
    }
    if b0_samples.is_empty() {
        return Err(ChooseError::NoSamples);
    }
    for b0 in b0_samples {
        if b0.iter().any(|c| c.len() != n) {
            return Err(ChooseError::SampleSize(n));
        }
    }
    let defaults;
    let candidates = if candidates.is_empty() {
        defaults = default_candidates();
        &defaults[..]
    } else {
        candidates
    };
    // The matrix is checked and prepared once here, not again for each
    // candidate: the sparse thresholds of all of them in one pass.
    let mut prepared = Prepared::new(t, n)?;
    prepared.prepare(
        &candidates
            .iter()
            .map(|&k| sparse_count(k, n))
            .collect::<Vec<_>>(),
    );
    // The exact H of every sample, once; each candidate is measured through
    // its f64 gather, without a decoded n × n copy.
    let reference = exact_products(t, n, b0_samples);
    // Cheapest first (by the bytes a setting is expected to take); once a
    // setting meets the bound, only those expected to be cheaper than it
    // still need trying.
    let mut order: Vec<CodecKind> = candidates.to_vec();
    order.sort_by(|a, b| expected_bytes_per_entry(*a).total_cmp(&expected_bytes_per_entry(*b)));
    let is_block = |k: CodecKind| matches!(k, CodecKind::Bc1Log { .. } | CodecKind::Bc4Log { .. });
    // The passing settings kept: the cheapest, and the cheapest block
    // setting after it (at most two encodings are held).
    let mut passing: Vec<(CodecKind, Encoded, f64)> = Vec::new();
    let mut tried = Vec::new();
    for kind in order {
        // Past the cheapest passing setting, only block settings within the
        // slack can still be chosen; past the cheapest passing block
        // setting, nothing can.
        let expected = expected_bytes_per_entry(kind);
        if let Some(b) = passing.first() {
            let limit = BLOCK_CODEC_SLACK * b.1.bytes_per_entry();
            if passing.iter().any(|p| is_block(p.0)) || expected > limit {
                break;
            }
            if !is_block(kind) {
                continue;
            }
        }
        // The estimate: 1 row of tiles in `stride` encoded and gathered.
        let estimate = if stride > 1 {
            let e = encode_prepared(kind, &prepared, stride)?;
            let est = h_error_estimate(&e, &reference, b0_samples, stride);
            if est.rejects(max_error) {
                let bpe = sampled_bytes_per_entry(&e, stride);
                let margin = est.margin();
                on_candidate(kind, est.error, bpe, Measured::Estimated { stride, margin });
                tried.push(format!(
                    "{kind}: {:.3e} (estimated, margin {margin:.2}) at {bpe:.3} B/entry",
                    est.error
                ));
                continue;
            }
            Some(est)
        } else {
            None
        };
        let e = encode_prepared(kind, &prepared, 1)?;
        let err = h_error(&e, &reference, b0_samples);
        on_candidate(kind, err, e.bytes_per_entry(), Measured::Full { estimate });
        tried.push(format!(
            "{kind}: {err:.3e} at {:.3} B/entry",
            e.bytes_per_entry()
        ));
        if err <= max_error {
            passing.push((kind, e, err));
        }
    }
    // The candidates come in order of expected bytes, which the real bytes
    // follow closely; compare the real ones.
    let Some(cheapest) = (0..passing.len()).min_by_key(|&i| passing[i].1.bytes_total()) else {
        return Err(ChooseError::NoCandidate {
            max_error,
            tried: tried.join("; "),
        });
    };
    let limit = BLOCK_CODEC_SLACK * passing[cheapest].1.bytes_total() as f64;
    let block = (0..passing.len())
        .filter(|&i| is_block(passing[i].0) && passing[i].1.bytes_total() as f64 <= limit)
        .min_by_key(|&i| passing[i].1.bytes_total());
    Ok(passing.swap_remove(block.unwrap_or(cheapest)))
}

/// The log settings among the [`default_candidates`] expected to cost no
/// more than `kind`: what the bake tries on the column-scaled matrix after
/// choosing `kind` on the plain one (`bake::run`).
pub fn log_candidates_no_dearer_than(kind: CodecKind) -> Vec<CodecKind> {
    let limit = expected_bytes_per_entry(kind);
    default_candidates()
        .into_iter()
        .filter(|k| k.log_params().is_some() && expected_bytes_per_entry(*k) <= limit)
        .collect()
}

/// The bytes per matrix entry a setting is expected to take for an RGB
/// matrix without zero tiles (module doc of the codec: the dense part's
/// rate plus, per sparse position, a 2-byte column and its values), used to
/// try the cheapest settings first.
pub fn expected_bytes_per_entry(kind: CodecKind) -> f64 {
    let sparse = |top: f64, s: SparseValues| {
        top * (2.0
            + match s {
                SparseValues::Rgb9e5 => 4.0,
                SparseValues::F16 => 6.0,
                SparseValues::F32 => 12.0,
            })
    };
    match kind {
        CodecKind::Bc1Log {
            top_fraction,
            sparse: s,
            ..
        } => 0.5 + sparse(top_fraction, s),
        CodecKind::Bc4Log {
            top_fraction,
            sparse: s,
            ..
        } => 1.5 + sparse(top_fraction, s),
        CodecKind::Bc6h => 1.0,
        CodecKind::F16 => 6.0,
        CodecKind::F32 => 12.0,
    }
}

/// The relative RMS error of `H̃ = T̃ B0` (computed from the encoding in
/// f64, [`Encoded::gather_f64`]) against the exact products `reference`
/// (`T B0` per sample and channel, e.g. from [`mat_vec`]), pooled over all
/// samples, channels and patches as in [`CodecError::rel_rms_h`].
pub fn h_error(e: &Encoded, reference: &[[Vec<f64>; 3]], b0_samples: &[[Vec<f32>; 3]]) -> f64 {
    // Every row of tiles: the estimate is the full measure.
    h_error_estimate(e, reference, b0_samples, 1).error
}

/// The bytes per entry the full encoding of a candidate is expected to
/// take, from its [`encode_sampled`](super::encode_sampled) form: the dense part and the tile
/// index scaled from the rows of tiles encoded to all of them; the sparse
/// part is already whole.
fn sampled_bytes_per_entry(e: &Encoded, stride: usize) -> f64 {
    let tps = e.index.tiles_per_side;
    let encoded = tps.div_ceil(stride.max(1));
    if e.n == 0 || encoded == 0 {
        return 0.0;
    }
    let scaled = (e.bytes_dense() + e.bytes_index()) as f64 * tps as f64 / encoded as f64;
    (scaled + e.bytes_sparse() as f64) / (e.n * e.n) as f64
}

/// [`h_error`] over every `stride`-th row of tiles only
/// ([`Encoded::gather_many_f64_sampled`]), the estimate the codec choice
/// rejects candidates on, with its standard error (stride 1: the full
/// measure, σ = 0). The estimate is a ratio
/// estimate, `R̂ = Σ d / Σ r` over the sampled rows of tiles `t` (`d_t` the
/// squared error of `H̃` over the tile row's patches, all samples and
/// channels, `r_t` the squared `H`), reported as `√R̂`. Its variance, with
/// `m` of `M` rows of tiles sampled (Cochran, *Sampling Techniques*, 3rd
/// ed., section 6.3, the ratio estimate's variance):
/// `v(R̂) = (1 − m/M) Σ (d_t − R̂ r_t)² / (m (m − 1) r̄²)`, `r̄ = Σ r / m`;
/// the square root's standard error is `√v / (2 √R̂)` (delta method).
pub fn h_error_estimate(
    e: &Encoded,
    reference: &[[Vec<f64>; 3]],
    b0_samples: &[[Vec<f32>; 3]],
    stride: usize,
) -> Estimate {
    let stride = stride.max(1);
    let tile = e.index.tile.max(1);
    let rows_of_tiles = e.n.div_ceil(tile);
    let (mut d2, mut r2) = (0.0f64, 0.0f64);
    // Per row of tiles, for the spread (the totals keep the order of
    // summation over patches, samples and channels).
    let (mut dt, mut rt) = (vec![0.0f64; rows_of_tiles], vec![0.0f64; rows_of_tiles]);
    // All samples in one pass over the matrix (each tile decoded once);
    // in groups, so that the accumulators of a row of tiles stay small.
    let mut gathered = Vec::with_capacity(b0_samples.len());
    for group in b0_samples.chunks(64) {
        let b0s: Vec<[&[f32]; 3]> = group.iter().map(|b| [&b[0][..], &b[1], &b[2]]).collect();
        gathered.extend(e.gather_many_f64_sampled(&b0s, stride));
    }
    for (h, g) in reference.iter().zip(&gathered) {
        for c in 0..3 {
            for (i, (a, b)) in h[c].iter().zip(&g[c]).enumerate() {
                if e.sampled_tile_rows(i, stride) {
                    let (d, r) = ((b - a) * (b - a), a * a);
                    d2 += d;
                    r2 += r;
                    dt[i / tile] += d;
                    rt[i / tile] += r;
                }
            }
        }
    }
    let error = ratio(d2.sqrt(), r2.sqrt());
    let sampled: Vec<usize> = (0..rows_of_tiles).step_by(stride).collect();
    let m = sampled.len();
    let std_error = if m >= rows_of_tiles || error == 0.0 {
        // Every row sampled (the full measure), or no error to spread.
        0.0
    } else if m < 2 || !(r2 > 0.0) || !error.is_finite() {
        // Too few rows to show a spread: the margin's upper bound applies.
        f64::INFINITY
    } else {
        let rhat = d2 / r2;
        let rbar = r2 / m as f64;
        let ss: f64 = sampled
            .iter()
            .map(|&t| (dt[t] - rhat * rt[t]).powi(2))
            .sum();
        let fpc = 1.0 - m as f64 / rows_of_tiles as f64;
        let var = fpc * ss / (m as f64 * (m as f64 - 1.0) * rbar * rbar);
        var.sqrt() / (2.0 * error)
    };
    Estimate {
        error,
        std_error,
        rows: m,
    }
}
