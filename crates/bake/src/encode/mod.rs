//! The encoder of the compressed transfer matrix (docs/design.md section 2,
//! "Compression"; bake step 6): the sparse top fraction, the log bytes, the
//! block fitting ([`bc1`], [`bc4`]), the mass correction, and the error
//! measures and codec choice ([`measure`](mod@measure)). What every
//! encoding of one matrix shares (the check, maxima, mass and the sparse
//! ranking's histograms) is made once per matrix (`prepared`), so the
//! choice's candidates do not each pass over the whole matrix for it. The
//! format it writes, and its decoder, are the contract's
//! ([`radiosity_bakefile::codec`], whose module doc describes every step).

pub mod bc1;
pub mod bc4;
pub mod log_bytes;
pub mod measure;
mod prepared;

pub use measure::{
    choose, choose_with, default_candidates, estimate_stride, exact_products, h_error,
    h_error_estimate, mat_vec, measure, CodecError, Estimate, Measured, BLOCK_CODEC_SLACK,
    ESTIMATE_MARGIN, ESTIMATE_MIN_MARGIN, ESTIMATE_MIN_STRIDE, ESTIMATE_STANDARD_ERRORS,
};

use bc1::encode_bc1_tile;
use bc4::encode_bc4_tile;
use half::f16;
use log_bytes::LogBytes;
use prepared::Prepared;
use radiosity_bakefile::codec::decode::{decode_tile_bytes, log_lut, Codebook};
use radiosity_bakefile::codec::rgb9e5;
use radiosity_bakefile::codec::{
    CodecKind, CodecSettingError, DenseFormat, EncodeStats, Encoded, Sparse, SparseValues,
    TileIndex, AUTO_FLUSH_QUANTILE, LOG_RANGE_AUTO, TILE,
};
use rayon::prelude::*;
use std::time::Instant;

/// Why a matrix cannot be encoded.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EncodeError {
    #[error(transparent)]
    Setting(#[from] CodecSettingError),
    #[error("transfer channel {channel} has {len} entries, expected n² for n = {n}")]
    Size {
        channel: usize,
        len: usize,
        n: usize,
    },
    #[error(
        "transfer entry ({row}, {col}) of channel {channel} is {value}: entries must be finite \
         and non-negative"
    )]
    Entry {
        row: usize,
        col: usize,
        channel: usize,
        value: f32,
    },
    #[error("{0} patches exceed the codec's limits (n² < 2^32)")]
    TooManyPatches(usize),
    #[error("the dense part takes {0} bytes, more than the 4 GiB its u32 offsets address")]
    DenseTooLarge(usize),
}

/// The power of two `s` with `max · s ∈ [2^14, 2^15)`: halves of values
/// times `s` stay below 65504 and normal down to `2^−29 · max`. 1 for 0.
fn pow2_scale(max: f32) -> f32 {
    if !(max > 0.0) {
        return 1.0;
    }
    let e = (max as f64).log2().floor() as i32;
    2f64.powi((14 - e).clamp(-100, 100)) as f32
}

/// The automatic log range: the smallest `L` that maps the
/// [`AUTO_FLUSH_QUANTILE`] quantile `v` of the nonzero dense values (of the
/// channel needing the widest range) to byte 1 or above,
/// `L = ln(M_c / v) / (1 − 1/510)`, clamped to [1, 30]. Each byte level
/// then spans the least ln-range for the data: at the synthetic room's
/// spread (5 e-folds below the maximum) levels are 5× finer than the
/// thesis's L = 25. The quantile is estimated on a deterministic subsample
/// of at most 2^20 entries per channel (every k-th in row-major order).
pub fn auto_log_range(
    max: &[f32],
    n: usize,
    dense: &(dyn Fn(usize, usize, usize) -> f32 + Sync),
) -> f32 {
    let total = n * n;
    let stride = total.div_ceil(1 << 20).max(1);
    let mut l = 1.0f64;
    for (c, &m) in max.iter().enumerate() {
        if !(m > 0.0) {
            continue;
        }
        // In parallel, in order: the same sample as a loop's.
        let mut sample: Vec<f32> = (0..total.div_ceil(stride))
            .into_par_iter()
            .map(|s| dense(c, s * stride / n, s * stride % n))
            .filter(|&v| v > 0.0)
            .collect();
        if sample.is_empty() {
            continue;
        }
        let k = ((sample.len() as f64 * AUTO_FLUSH_QUANTILE) as usize).min(sample.len() - 1);
        let (_, v, _) = sample.select_nth_unstable_by(k, f32::total_cmp);
        let range = (m as f64 / *v as f64).ln() / (1.0 - 1.0 / 510.0);
        l = l.max(range);
    }
    l.clamp(1.0, 30.0) as f32
}

/// The entries a setting keeps in its sparse part: its top fraction of the
/// `n²`, rounded (0 for the formats without one).
fn sparse_count(kind: CodecKind, n: usize) -> usize {
    let top_fraction = kind.log_params().map_or(0.0, |p| p.0);
    (top_fraction * (n * n) as f64).round() as usize
}

/// Positions of the sparse part as a bitset over the n² entries.
struct Mask {
    bits: Vec<u64>,
    n: usize,
}

impl Mask {
    fn contains(&self, i: usize, j: usize) -> bool {
        let k = i * self.n + j;
        self.bits[k / 64] >> (k % 64) & 1 == 1
    }
}

/// Per-tile counts gathered while encoding.
#[derive(Clone, Copy, Default)]
pub struct TileCounts {
    flushed: u64,
    mixed: u64,
    zeros_lost: u64,
    /// Per stored channel: the sum of the tile's dense values and of their
    /// decoded values (for the mass correction of the log formats).
    sum_source: [f64; 3],
    sum_decoded: [f64; 3],
}

/// Encodes the three channels of the n × n row-major matrix `t` (entries
/// finite and ≥ 0) with `kind` (module doc). Deterministic: the same input
/// gives the same bytes.
pub fn encode(kind: CodecKind, t: [&[f32]; 3], n: usize) -> Result<Encoded, EncodeError> {
    encode_in(kind, t, n, 1)
}

/// [`encode`] of 1 row of tiles in `stride` only (tile rows `tr` with
/// `tr % stride == 0`; the others are stored as empty tiles and read as
/// 0), for the codec choice's estimate
/// ([`measure::h_error_estimate`]). The sparse part, the scales and
/// the log range are the full encoding's, and so are the encoded tiles'
/// bytes; only the log formats' mass correction differs, taken over the
/// encoded tiles instead of all. The dense work is 1/`stride` of
/// [`encode`]'s.
pub fn encode_sampled(
    kind: CodecKind,
    t: [&[f32]; 3],
    n: usize,
    stride: usize,
) -> Result<Encoded, EncodeError> {
    encode_in(kind, t, n, stride.max(1))
}

/// [`encode`] with only 1 row of tiles in `stride` encoded.
fn encode_in(
    kind: CodecKind,
    t: [&[f32]; 3],
    n: usize,
    stride: usize,
) -> Result<Encoded, EncodeError> {
    let prepared = Prepared::new(t, n)?;
    encode_prepared(kind, &prepared, stride)
}

/// [`encode_in`] of a checked matrix with what every encoding of it shares
/// ([`Prepared`]): the codec choice checks and prepares its matrix once for
/// all its candidates.
fn encode_prepared(kind: CodecKind, p: &Prepared, stride: usize) -> Result<Encoded, EncodeError> {
    let start = Instant::now();
    kind.validate()?;
    let (t, n) = (p.t, p.n);
    let distinct = &p.distinct;
    let grey = distinct.len() == 1;
    let format = DenseFormat::of(kind, distinct.len());
    // BC6H always stores RGB; the others store the distinct channels.
    let stored: Vec<&[f32]> = if format == DenseFormat::Bc6h {
        t.to_vec()
    } else {
        distinct.clone()
    };
    let ch = stored.len();

    // The sparse part (log formats, which store the distinct channels).
    let (_, log_range, sparse_values) = kind.log_params().unwrap_or((0.0, 0.0, SparseValues::F32));
    let selection = p.select(sparse_count(kind, n));
    let mut mask = Mask {
        bits: vec![0u64; (n * n).div_ceil(64)],
        n,
    };
    let (row_ptr, cols) = (selection.row_ptr, selection.cols);
    let mut values = Vec::with_capacity(cols.len() * ch);
    for (i, w) in row_ptr.windows(2).enumerate() {
        for &j in &cols[w[0] as usize..w[1] as usize] {
            let k = i * n + j as usize;
            mask.bits[k / 64] |= 1 << (k % 64);
            values.extend(stored.iter().map(|c| c[k]));
        }
    }
    let mut sparse_scale = [1.0f32; 3];
    // One channel has no exponent to share: f16 is cheaper (type doc).
    let sparse_values = if sparse_values == SparseValues::Rgb9e5 && ch == 1 {
        SparseValues::F16
    } else {
        sparse_values
    };
    if sparse_values == SparseValues::Rgb9e5 {
        let m = values.iter().cloned().fold(0.0f32, f32::max);
        sparse_scale = [pow2_scale(m); 3];
        for v in values.chunks_exact_mut(3) {
            let s = sparse_scale[0];
            let packed = rgb9e5::pack([v[0] * s, v[1] * s, v[2] * s]);
            let back = rgb9e5::unpack(packed);
            for c in 0..3 {
                v[c] = back[c] / s;
            }
        }
    }
    if sparse_values == SparseValues::F16 {
        for (c, s) in sparse_scale.iter_mut().enumerate().take(ch) {
            let m = values
                .iter()
                .skip(c)
                .step_by(ch)
                .cloned()
                .fold(0.0f32, f32::max);
            *s = pow2_scale(m);
        }
        for (k, v) in values.iter_mut().enumerate() {
            let s = sparse_scale[k % ch];
            *v = f16::from_f32(*v * s).to_f32() / s;
        }
    }
    let sparse_mass: f64 = values.iter().map(|&v| v as f64).sum();
    // The distinct channels' mass: BC6H, which stores three copies of a
    // grey matrix, has no sparse part, so its fraction is 0 either way.
    let total_mass = p.total_mass;
    let has_sparse = !cols.is_empty();
    let sparse = Sparse {
        row_ptr: if has_sparse { row_ptr } else { Vec::new() },
        cols,
        values,
        precision: sparse_values,
        scale: sparse_scale,
    };

    // The dense part's scales: the maximum of what is left (log formats),
    // or a power of two (halves).
    let dense_value = |c: usize, i: usize, j: usize| -> f32 {
        if i < n && j < n && !(has_sparse && mask.contains(i, j)) {
            stored[c][i * n + j]
        } else {
            0.0
        }
    };
    let mut scale = [1.0f32; 3];
    for (c, s) in scale.iter_mut().enumerate().take(ch) {
        // With a sparse part the channels stored are the distinct ones.
        let m = if has_sparse {
            selection.dense_max[c]
        } else {
            p.maxima[c]
        };
        *s = match format {
            DenseFormat::Bc1 | DenseFormat::Bc4 => m,
            DenseFormat::Bc6h | DenseFormat::F16 => pow2_scale(m),
            DenseFormat::F32 => 1.0,
        };
    }
    if grey && ch == 1 {
        scale = [scale[0]; 3];
    }
    let log_range = if kind.log_params().is_some() && log_range == LOG_RANGE_AUTO {
        auto_log_range(&scale[..ch], n, &dense_value)
    } else {
        log_range
    };

    // The tiles, in parallel; each is prepared, tested for emptiness and
    // encoded independently, so the result does not depend on scheduling.
    let image_size = if format.is_block() {
        n.div_ceil(4) * 4
    } else {
        n
    };
    let tps = image_size.div_ceil(TILE);
    let book = Codebook {
        format,
        channels: ch,
        lut: std::array::from_fn(|c| {
            if matches!(format, DenseFormat::Bc1 | DenseFormat::Bc4) {
                log_lut(scale[c], log_range)
            } else {
                [0.0; 256]
            }
        }),
        max: scale,
        log_range,
        inv_scale: scale.map(|s| 1.0 / s),
    };
    // The log bytes' thresholds, once per channel (log formats only).
    let log_bytes: Vec<LogBytes> = if matches!(format, DenseFormat::Bc1 | DenseFormat::Bc4) {
        (0..ch)
            .map(|c| LogBytes::new(scale[c], log_range))
            .collect()
    } else {
        Vec::new()
    };
    let tiles: Vec<(Option<Vec<u8>>, TileCounts)> = (0..tps * tps)
        .into_par_iter()
        .map(|k| {
            let (tr, tc) = (k / tps, k % tps);
            if !tr.is_multiple_of(stride) {
                return (None, TileCounts::default());
            }
            let (r0, c0) = (tr * TILE, tc * TILE);
            let (h, w) = (TILE.min(image_size - r0), TILE.min(image_size - c0));
            // `dense_value` over the tile, a row slice at a time: the
            // matrix's entries (0 past its edge), sparse positions cleared.
            let mut vals = vec![0.0f32; h * w * ch];
            let wn = w.min(n.saturating_sub(c0));
            for r in 0..h.min(n.saturating_sub(r0)) {
                let (i, out) = (r0 + r, &mut vals[r * w * ch..(r * w + wn) * ch]);
                for (k, st) in stored.iter().enumerate() {
                    let src = &st[i * n + c0..i * n + c0 + wn];
                    for (o, &v) in out.iter_mut().skip(k).step_by(ch).zip(src) {
                        *o = v;
                    }
                }
                if has_sparse {
                    for c in 0..wn {
                        if mask.contains(i, c0 + c) {
                            out[c * ch..(c + 1) * ch].fill(0.0);
                        }
                    }
                }
            }
            encode_tile(&book, &log_bytes, &vals, h, w)
        })
        .collect();

    let mut index = TileIndex {
        tile: TILE,
        tiles_per_side: tps,
        row_start: Vec::with_capacity(tps + 1),
        cols: Vec::new(),
        offsets: Vec::new(),
    };
    let mut dense = Vec::new();
    let mut counts = TileCounts::default();
    index.row_start.push(0);
    for tr in 0..tps {
        for tc in 0..tps {
            let (bytes, tcnt) = &tiles[tr * tps + tc];
            if let Some(bytes) = bytes {
                index.cols.push(tc as u16);
                index.offsets.push(dense.len() as u32);
                dense.extend_from_slice(bytes);
            }
            counts.flushed += tcnt.flushed;
            counts.mixed += tcnt.mixed;
            counts.zeros_lost += tcnt.zeros_lost;
            for c in 0..3 {
                counts.sum_source[c] += tcnt.sum_source[c];
                counts.sum_decoded[c] += tcnt.sum_decoded[c];
            }
        }
        index.row_start.push(index.cols.len() as u32);
    }
    drop(tiles);
    // Mass correction of the log formats (module doc): the decoded dense
    // part keeps the sum of each channel.
    let mut mass_correction = [1.0f64; 3];
    if matches!(format, DenseFormat::Bc1 | DenseFormat::Bc4) {
        for c in 0..ch {
            if counts.sum_decoded[c] > 0.0 {
                mass_correction[c] = counts.sum_source[c] / counts.sum_decoded[c];
                scale[c] = (scale[c] as f64 * mass_correction[c]) as f32;
            }
        }
        if ch == 1 {
            scale = [scale[0]; 3];
        }
    }
    if dense.len() > u32::MAX as usize {
        return Err(EncodeError::DenseTooLarge(dense.len()));
    }
    let tiles_total = tps * tps;
    let tiles_stored = index.cols.len();
    let stats = EncodeStats {
        seconds: start.elapsed().as_secs_f64(),
        grey,
        tiles_total,
        tiles_stored,
        tiles_skipped_fraction: if tiles_total > 0 {
            (tiles_total - tiles_stored) as f64 / tiles_total as f64
        } else {
            0.0
        },
        sparse_entries: sparse.len(),
        sparse_mass_fraction: if total_mass > 0.0 {
            sparse_mass / total_mass
        } else {
            0.0
        },
        flushed_entries: counts.flushed,
        mixed_zero_blocks: counts.mixed,
        zeros_lost: counts.zeros_lost,
        mass_correction,
    };
    Ok(Encoded {
        kind,
        n,
        channels: ch,
        format,
        image_size,
        scale,
        log_range: if kind.log_params().is_some() {
            log_range
        } else {
            0.0
        },
        index,
        dense,
        sparse,
        col_scale: Vec::new(),
        stats,
    })
}

/// Encodes one tile of dense values (texel-major, `channels` per texel);
/// the bytes are `None` when the tile stores nothing (every stored value
/// would be 0). Also decodes the result to count zeros the format did not
/// keep.
fn encode_tile(
    book: &Codebook,
    log_bytes: &[LogBytes],
    vals: &[f32],
    h: usize,
    w: usize,
) -> (Option<Vec<u8>>, TileCounts) {
    let scale = &book.max;
    let ch = book.channels;
    let mut counts = TileCounts::default();
    let bytes = match book.format {
        DenseFormat::Bc1 | DenseFormat::Bc4 => {
            let q: Vec<u8> = vals
                .iter()
                .enumerate()
                .map(|(k, &v)| log_bytes[k % ch].byte(v))
                .collect();
            counts.flushed = vals
                .iter()
                .zip(&q)
                .filter(|&(&v, &b)| v > 0.0 && b == 0)
                .count() as u64;
            if q.iter().all(|&b| b == 0) {
                return (None, counts);
            }
            if book.format == DenseFormat::Bc1 {
                encode_bc1_tile(&q, h, w, &mut counts)
            } else {
                encode_bc4_tile(&q, h, w, ch, &mut counts)
            }
        }
        DenseFormat::Bc6h | DenseFormat::F16 => {
            let halves: Vec<u16> = vals
                .iter()
                .enumerate()
                .map(|(k, &v)| f16::from_f32(v * scale[k % ch]).to_bits())
                .collect();
            counts.flushed = vals
                .iter()
                .zip(&halves)
                .filter(|&(&v, &b)| v > 0.0 && b == 0)
                .count() as u64;
            if halves.iter().all(|&b| b == 0) {
                return (None, counts);
            }
            if book.format == DenseFormat::F16 {
                halves.iter().flat_map(|b| b.to_le_bytes()).collect()
            } else {
                // RGBA halves, alpha 1.0 (ignored by BC6H).
                let one = f16::ONE.to_bits();
                let mut rgba = Vec::with_capacity(h * w * 8);
                for t in halves.chunks(3) {
                    for &b in t.iter().chain(std::iter::once(&one)) {
                        rgba.extend_from_slice(&b.to_le_bytes());
                    }
                }
                let surface = intel_tex_2::RgbaSurface {
                    data: &rgba,
                    width: w as u32,
                    height: h as u32,
                    stride: (w * 8) as u32,
                };
                intel_tex_2::bc6h::compress_blocks(&intel_tex_2::bc6h::basic_settings(), &surface)
            }
        }
        DenseFormat::F32 => {
            if vals.iter().all(|&v| v == 0.0) {
                return (None, counts);
            }
            vals.iter().flat_map(|v| v.to_le_bytes()).collect()
        }
    };
    // Zeros the format did not keep.
    let mut decoded = vec![0.0f32; h * w * ch];
    decode_tile_bytes(book, &bytes, h, w, &mut decoded);
    counts.zeros_lost = vals
        .iter()
        .zip(&decoded)
        .filter(|&(&v, &d)| v == 0.0 && d != 0.0)
        .count() as u64;
    for (k, (&v, &d)) in vals.iter().zip(&decoded).enumerate() {
        counts.sum_source[k % ch] += v as f64;
        counts.sum_decoded[k % ch] += d as f64;
    }
    (Some(bytes), counts)
}
