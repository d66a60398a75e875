//! The compressed transfer matrix (DESIGN.md section 2, "Compression"; bake
//! step 6): encoders for the three channels of the n × n transfer matrix
//! `T`, the decoder the run time mirrors, the product `H = T̃ · B0` computed
//! from the compressed form, error measures, and the choice of the cheapest
//! setting under an error bound.
//!
//! # Layout
//!
//! An [`Encoded`] matrix has three parts; their bytes are counted separately
//! and together in every bytes-per-entry figure.
//!
//! **Dense part.** An `S × S` image (`S = n`, or `n` rounded up to a
//! multiple of 4 for the block formats; padding is zero) whose texel (i, j)
//! holds entry (i, j) of the three channels. It is cut into square tiles of
//! [`TILE`] texels (edge tiles are smaller); a tile whose dense values are
//! zero in every channel is not stored (and not read by [`Encoded::gather`]).
//! Stored tiles are concatenated, row of tiles by row of tiles; inside a
//! tile, 4 × 4 blocks (or texels, for the plain formats) are row-major.
//!
//! **Tile index.** Per row of tiles, the stored tiles' columns (u16) and
//! byte offsets (u32), CSR-style ([`TileIndex`]). 32 × 32 tiles keep the
//! index near 1 % of a BC1 dense part (6 bytes per 512-byte tile) while
//! still resolving the zero regions of block-sparse matrices (closed rooms,
//! zero-albedo columns, `F` itself).
//!
//! **Sparse part.** The top fraction of entries (log formats): a CSR
//! matrix with one column index per *position* and the values of all stored
//! channels for it, exact in f32, or f16 per channel, or the three channels
//! in one shared-exponent RGB9E5 word ([`SparseValues`]). Columns are
//! u16 while `n ≤ 65536`, else u32; row pointers are u32.
//!
//! # Formats ([`CodecKind`])
//!
//! - [`CodecKind::Bc1Log`], the thesis's codec, made exact where it was not:
//!   1. *Top fraction.* Positions are ranked by `Σ_c T_c(i,j) / max T_c`
//!      (each channel normalised by its maximum, so each counts alike), and
//!      the top `⌊f · n²⌉` positions (ties in row-major order) are stored in
//!      the sparse part and set to zero in the dense one. One ranking for all
//!      channels, not one per channel: one column index then serves three
//!      values, and the dense texel at a sparse position is zero in all three
//!      channels, which BC1 can decode exactly (below). The ranking is
//!      global, not per row: BC1-log's error is relative, so the largest
//!      entries carry the largest absolute errors, and removing the globally
//!      largest ones is what lowers `‖T̃ − T‖_F` (and H's error) most for a
//!      given count.
//!   2. *Log scale.* The rest, divided by its per-channel maximum `M_c`, is
//!      mapped to a byte `q = round(255 · (ln(t/M_c) + L) / L)` clamped to
//!      [0, 255]; exact zeros map to 0, and byte 0 decodes to exactly 0.
//!      Byte `q ≥ 1` decodes to `M_c · e^{L (q/255 − 1)}`: within a factor
//!      `e^{±L/510}` of `t`. Nonzero entries below `M_c e^{−L (1 − 1/510)}`
//!      become 0: counted (`flushed_entries`).
//!      *The range L.* The thesis fixes L = 25 (bytes span `e^{−25}`, far
//!      more than transfer matrices need: the synthetic room's dense part
//!      spans 5 e-folds). `L = 0` ([`LOG_RANGE_AUTO`], the default) takes
//!      the smallest L that keeps all but the smallest 0.1 % of nonzero
//!      dense entries ([`auto_log_range`]): every byte level is then as
//!      fine as the data allow (6× finer than L = 25 on the room, and BC1's
//!      5-bit endpoint grid with it), for the same bytes.
//!   3. *BC1.* The bytes of the three channels are the R, G, B of the
//!      image, encoded by `intel_tex_2` (ISPC, BC1 in 4-colour mode), then
//!      checked and refined per block:
//!      - blocks without black texels: the encoder occasionally emits
//!        `c0 ≤ c1` (3-colour mode, whose index 3 decodes to black); such
//!        blocks are rebuilt in 4-colour mode. Then the endpoints are
//!        refitted by least squares for the block's indices (two rounds,
//!        each kept only if the block's squared error drops). This cuts the
//!        encoder's systematic bias (on smooth data about −0.3 of a level in
//!        G and B; the room's channel sums at L = 12 came out 1.4–1.7 % low
//!        in R and G, within 0.8 % after) and lowers H's error by ~25 %;
//!      - blocks whose texels are all black (0, 0, 0): an all-zero block;
//!      - *mixed* blocks (black and non-black texels): encoded with their
//!        black texels replaced by the mean of the others (so that they do
//!        not pull the endpoints), then rewritten in BC1's 3-colour mode
//!        (`c0 ≤ c1`), whose index 3 is black on every decoder: black
//!        texels take index 3, the others the nearest palette colour, and
//!        the endpoints are refitted for the palette `c0, c1, (c0 + c1)/2`;
//!      - so exact zeros, the sparse positions and the flushed entries decode
//!        to exactly 0 wherever all three channels of the texel are 0, the
//!        common case (zeros come from geometry, which all channels share). A
//!        texel zero in some channels only can decode nonzero there: counted
//!        (`zeros_lost`). Keeping the dense texel at a sparse position at the
//!        channel maximum instead (and storing the difference) was measured
//!        too: it is worse (H error 1.13 % against 0.98 % on the room at
//!        L = 6, top 2 %), and it would make the sparse entries depend on the
//!        GPU's BC1 rounding.
//!   4. *Mass correction.* After encoding, each channel's `M_c` is
//!      multiplied by `κ_c = Σ T_dense / Σ T̃_dense`, so that the decoded
//!      dense part keeps each channel's sum: what is left of BC1's bias
//!      would otherwise add up coherently in `H = T̃ B0` (κ is within 1 % of
//!      1 at the automatic L, 3 % at L = 25; H's error drops by ~8 %).
//!
//!   A grey matrix (three equal channels) is stored as one BC4 channel
//!   instead: the same 0.5 bytes per entry, with 8-bit endpoints and 8
//!   levels per block instead of 5/6-bit endpoints and 4 levels.
//! - [`CodecKind::Bc4Log`]: the same log bytes, sparse part and mass
//!   correction, each channel its own BC4 image (0.5 bytes per entry per
//!   channel; one for grey). Blocks mixing zero and nonzero bytes take the
//!   better of the encoder's block (if it keeps the zeros) and a 6-level
//!   block (`r0 ≤ r1`, whose index 6 is exactly 0) with endpoints searched
//!   within ±2 of the smallest and largest nonzero byte. (Keeping the
//!   encoder's block whenever it keeps the zeros, through an endpoint at 0,
//!   spends the block's 8 levels on the gap to 0 and doubled H's error.)
//!   Decoded at float precision (GPUs interpolate BC4 at more than 8 bits).
//! - [`CodecKind::Bc6h`]: half-float endpoints, no log transform and no
//!   sparse part (BC6H's endpoints interpolate on the half-float bit
//!   patterns, already nearly logarithmic); `intel_tex_2`'s basic settings.
//!   Each channel is multiplied by a power of two putting its maximum in
//!   [2^14, 2^15), so that values down to `2^−29` of the maximum stay
//!   normal halves. Zeros are kept only in skipped tiles and where the
//!   encoder happens to keep them; the others are counted (`zeros_lost`).
//! - [`CodecKind::F16`]: halves with the same power-of-two scale (relative
//!   error ≤ 2^−11 for values ≥ 2^−29 of the channel maximum).
//! - [`CodecKind::F32`], exact.
//!
//! # Decoding as the run time does
//!
//! The run time maps a BC1/BC4 texel `x ∈ [0, 1]` to `M_c · e^{L (x − 1)}`
//! for `x > 0` and to 0 for `x = 0` (`texelFetch`, no filtering).
//! [`decode`] and [`Encoded::gather`] decode BC1 with `bcdec_rs`, which
//! rounds the interpolated colours to the nearest of 256 levels, and map
//! the byte through a 256-entry table. Hardware that interpolates at higher
//! precision differs from this by at most half a level (a factor
//! `e^{L/510}`); Mesa llvmpipe truncates (TOOLCHAIN.md), up to one level
//! low (`e^{L/255}`: 1.6 % at the room's automatic L ≈ 4, 10 % at L = 25),
//! a bias the run-time tests must allow for. BC4, BC6H and the plain
//! formats decode at float precision. Black texels (BC1 index 3 in 3-colour
//! mode, BC4 index 6 in 6-level mode) are exactly 0 on every decoder.
//!
//! # Bytes per entry
//!
//! [`Encoded::bytes_per_entry`] = all bytes (dense + sparse + index) / n²:
//! per matrix entry with its three channels together, as the thesis's
//! "1.5 bytes per matrix entry (3 channels)". BC1 alone is 0.5, BC6H 1,
//! BC4 1.5 (0.5 grey), F16 6 (2 grey), F32 12 (4 grey); a sparse position
//! adds 6 bytes (u16 column, one RGB9E5 word), 8 (three f16) or 14 (three
//! f32), so a top fraction f adds 6f, 8f or 14f.
//!
//! # Choosing a codec
//!
//! [`choose`] encodes every candidate, measures the relative RMS error of
//! `H = T̃ · B0` over sample lights through the f64 gather ([`h_error`]: no
//! decoded n × n copy), and keeps the cheapest whose error is within the
//! bound. [`measure`] adds the per-entry and Frobenius errors of a decoded
//! matrix; [`report_rows`] and [`report_table`] tabulate errors, bytes and
//! times for every reordering and codec. [`synthetic`] builds test
//! matrices with the structure of real ones.

use crate::bake::reorder::{self, ReorderMethod};

use crate::core::compute::Backend;
use crate::core::error::BakeError;
use crate::core::patch::Patch;
use crate::core::permutation::Permutation;
use half::f16;
use rayon::prelude::*;
use serde::Serialize;
use std::fmt::Write as _;
use std::time::Instant;

/// Edge of a tile of the dense part, in texels (a multiple of 4).
pub const TILE: usize = 32;

/// The largest tile edge a valid encoding may declare (the reader's bound;
/// the encoder uses [`TILE`]).
pub const MAX_TILE: usize = 1024;

/// The thesis's log range `L`: bytes span `[e^{−L}, 1]` of the maximum.
pub const DEFAULT_LOG_RANGE: f32 = 25.0;

/// `log_range` value asking for the range to be chosen from the data
/// ([`auto_log_range`]).
pub const LOG_RANGE_AUTO: f32 = 0.0;

/// The share of the smallest nonzero dense entries an automatic log range
/// may flush to zero.
pub const AUTO_FLUSH_QUANTILE: f64 = 1e-3;

/// The thesis's top fraction stored exactly.
pub const DEFAULT_TOP_FRACTION: f64 = 0.04;

/// The stage name in errors.
const STAGE: &str = "codec";

/// Precision of the sparse part's values.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub enum SparseValues {
    /// Exact.
    #[default]
    F32,
    /// Relative error ≤ 2^−11 (each channel scaled by a power of two so its
    /// largest sparse value is a normal half near 2^15).
    F16,
    /// The three channels of a position in 4 bytes, OpenGL's shared-exponent
    /// format `GL_RGB9_E5` (EXT_texture_shared_exponent): three 9-bit
    /// mantissas and one 5-bit exponent, rounded as that specification
    /// says. Each channel errs by at most 2^−9 of the position's largest
    /// channel (its mantissa is ≥ 256 when rounded to nearest; true while
    /// that channel is above 2^−16, which the scale ensures), after one
    /// power-of-two scale common to the channels puts the largest sparse
    /// value near 2^15. A grey matrix (one channel) has nothing to share:
    /// its values are stored as f16, which is cheaper.
    Rgb9e5,
}

/// A codec setting (module doc).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub enum CodecKind {
    /// BC1 of the log-scaled bytes plus an exact sparse top fraction.
    Bc1Log {
        top_fraction: f64,
        log_range: f32,
        sparse: SparseValues,
    },
    /// BC4 per channel of the log-scaled bytes plus a sparse top fraction.
    Bc4Log {
        top_fraction: f64,
        log_range: f32,
        sparse: SparseValues,
    },
    /// BC6H (unsigned half floats), power-of-two scaled per channel.
    Bc6h,
    /// Half floats, power-of-two scaled per channel.
    F16,
    /// Plain f32.
    F32,
}

impl Default for CodecKind {
    /// DESIGN.md's setting: BC1 + log + the top 4 % kept in the sparse
    /// part, with the log range chosen from the data ([`auto_log_range`])
    /// rather than the thesis's fixed L = 25, which costs accuracy at no
    /// saving, and the sparse values as shared-exponent RGB9E5 rather than
    /// f32 (4 bytes a position for three channels instead of 12): their
    /// error (≤ 2^-9 of a position's largest channel) is two orders below
    /// BC1's, and on every scene of `docs/compression.md` the H error with
    /// RGB9E5, f16 and f32 sparse values agrees to within 1 % of itself,
    /// while the bytes per entry drop from 1.07 (f32) and 0.83 (f16) to
    /// 0.75 at the top 4 %.
    fn default() -> Self {
        CodecKind::Bc1Log {
            top_fraction: DEFAULT_TOP_FRACTION,
            log_range: LOG_RANGE_AUTO,
            sparse: SparseValues::Rgb9e5,
        }
    }
}

impl CodecKind {
    /// The thesis's setting: BC1 + log with L = 25 + the top 4 % exact.
    pub const THESIS: CodecKind = CodecKind::Bc1Log {
        top_fraction: DEFAULT_TOP_FRACTION,
        log_range: DEFAULT_LOG_RANGE,
        sparse: SparseValues::F32,
    };

    /// A short name for tables and logs, e.g. `bc1-log(top=0.04,L=25,f32)`;
    /// [`CodecKind::parse`] reads it back.
    pub fn name(&self) -> String {
        let log = |f: &str, top: f64, l: f32, s: SparseValues| {
            let s = match s {
                SparseValues::F32 => "f32",
                SparseValues::F16 => "f16",
                SparseValues::Rgb9e5 => "rgb9e5",
            };
            if l == LOG_RANGE_AUTO {
                format!("{f}(top={top},L=auto,{s})")
            } else {
                format!("{f}(top={top},L={l},{s})")
            }
        };
        match *self {
            CodecKind::Bc1Log {
                top_fraction,
                log_range,
                sparse,
            } => log("bc1-log", top_fraction, log_range, sparse),
            CodecKind::Bc4Log {
                top_fraction,
                log_range,
                sparse,
            } => log("bc4-log", top_fraction, log_range, sparse),
            CodecKind::Bc6h => "bc6h".into(),
            CodecKind::F16 => "f16".into(),
            CodecKind::F32 => "f32".into(),
        }
    }

    /// Parses `f32`, `f16`, `bc6h`, `bc1`, `bc4`, or `bc1`/`bc4` with
    /// options: `bc1(top=0.02,L=16,f16)` or `bc1:top=0.02,L=auto,sparse=f16`
    /// (any subset; the defaults are [`CodecKind::default`]'s: top = 0.04,
    /// L = auto, rgb9e5). [`CodecKind::name`] is read back.
    pub fn parse(s: &str) -> Result<CodecKind, BakeError> {
        let t = s.trim().to_ascii_lowercase();
        let bad = |why: String| {
            BakeError::Options(format!(
                "invalid codec {s:?}: {why} (expected f32, f16, bc6h, bc1 or bc4, e.g. \
                 bc1:top=0.04,L=25,sparse=f32)"
            ))
        };
        let (head, opts) = match t.find([':', '(']) {
            Some(p) => (&t[..p], t[p + 1..].trim_end_matches(')')),
            None => (t.as_str(), ""),
        };
        let head = head.trim_end_matches("-log");
        let (mut top, mut l, mut sparse) =
            (DEFAULT_TOP_FRACTION, LOG_RANGE_AUTO, SparseValues::Rgb9e5);
        for opt in opts.split(',').map(str::trim).filter(|o| !o.is_empty()) {
            let (k, v) = opt.split_once('=').unwrap_or(("sparse", opt));
            match k.trim() {
                "top" => top = v.trim().parse().map_err(|_| bad(format!("top={v}")))?,
                "l" if v.trim() == "auto" => l = LOG_RANGE_AUTO,
                "l" => l = v.trim().parse().map_err(|_| bad(format!("L={v}")))?,
                "sparse" => {
                    sparse = match v.trim() {
                        "f32" => SparseValues::F32,
                        "f16" => SparseValues::F16,
                        "rgb9e5" | "e5" => SparseValues::Rgb9e5,
                        _ => return Err(bad(format!("sparse={v}"))),
                    }
                }
                other => return Err(bad(format!("unknown option {other:?}"))),
            }
        }
        let kind = match head {
            "bc1" => CodecKind::Bc1Log {
                top_fraction: top,
                log_range: l,
                sparse,
            },
            "bc4" => CodecKind::Bc4Log {
                top_fraction: top,
                log_range: l,
                sparse,
            },
            "bc6h" | "f16" | "f32" if !opts.is_empty() => {
                return Err(bad(format!("{head} takes no options")))
            }
            "bc6h" => CodecKind::Bc6h,
            "f16" => CodecKind::F16,
            "f32" => CodecKind::F32,
            _ => return Err(bad(format!("unknown codec {head:?}"))),
        };
        kind.validate()?;
        Ok(kind)
    }

    /// Checks the parameters' ranges.
    pub fn validate(&self) -> Result<(), BakeError> {
        if let CodecKind::Bc1Log {
            top_fraction,
            log_range,
            ..
        }
        | CodecKind::Bc4Log {
            top_fraction,
            log_range,
            ..
        } = *self
        {
            if !(0.0..=1.0).contains(&top_fraction) {
                return Err(BakeError::Options(format!(
                    "top fraction must lie in [0, 1], got {top_fraction}"
                )));
            }
            if !(log_range.is_finite() && log_range >= 0.0) {
                return Err(BakeError::Options(format!(
                    "log range L must be a positive number or 0 (automatic), got {log_range}"
                )));
            }
        }
        Ok(())
    }

    /// The same setting with another top fraction: an error for the
    /// formats without a sparse part.
    pub fn with_top_fraction(self, f: f64) -> Result<CodecKind, BakeError> {
        let kind = match self {
            CodecKind::Bc1Log {
                log_range, sparse, ..
            } => CodecKind::Bc1Log {
                top_fraction: f,
                log_range,
                sparse,
            },
            CodecKind::Bc4Log {
                log_range, sparse, ..
            } => CodecKind::Bc4Log {
                top_fraction: f,
                log_range,
                sparse,
            },
            other => {
                return Err(BakeError::Options(format!(
                    "--top-fraction applies to the bc1 and bc4 codecs, not {other}"
                )))
            }
        };
        kind.validate()?;
        Ok(kind)
    }

    /// The (top fraction, log range, sparse precision) of the log formats.
    fn log_params(&self) -> Option<(f64, f32, SparseValues)> {
        match *self {
            CodecKind::Bc1Log {
                top_fraction,
                log_range,
                sparse,
            }
            | CodecKind::Bc4Log {
                top_fraction,
                log_range,
                sparse,
            } => Some((top_fraction, log_range, sparse)),
            _ => None,
        }
    }
}

impl std::fmt::Display for CodecKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.name())
    }
}

/// The format of the dense part's tiles.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum DenseFormat {
    /// One BC1 image, RGB = the three channels (8 bytes per 4 × 4 block).
    Bc1,
    /// One BC4 image per stored channel (8 bytes per block and channel).
    Bc4,
    /// One BC6H image, RGB (16 bytes per block).
    Bc6h,
    /// Half floats, stored channels interleaved per texel.
    F16,
    /// f32, stored channels interleaved per texel.
    F32,
}

impl DenseFormat {
    /// Whether the image is padded to a multiple of 4 (block formats).
    pub fn is_block(self) -> bool {
        matches!(
            self,
            DenseFormat::Bc1 | DenseFormat::Bc4 | DenseFormat::Bc6h
        )
    }

    /// Bytes of an h × w tile with `channels` stored channels.
    pub fn tile_bytes(self, h: usize, w: usize, channels: usize) -> usize {
        let blocks = (h / 4) * (w / 4);
        match self {
            DenseFormat::Bc1 => blocks * 8,
            DenseFormat::Bc4 => blocks * 8 * channels,
            DenseFormat::Bc6h => blocks * 16,
            DenseFormat::F16 => h * w * channels * 2,
            DenseFormat::F32 => h * w * channels * 4,
        }
    }
}

/// Which tiles of the dense part are stored, CSR over rows of tiles.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct TileIndex {
    /// Tile edge in texels.
    pub tile: usize,
    /// Tiles per row (and per column) of the image: `⌈S / tile⌉`.
    pub tiles_per_side: usize,
    /// Stored tiles of tile row `r` are entries `row_start[r]..row_start[r+1]`.
    pub row_start: Vec<u32>,
    /// Tile column of each stored tile, increasing within a tile row.
    pub cols: Vec<u16>,
    /// Byte offset of each stored tile in the dense data.
    pub offsets: Vec<u32>,
}

/// The exact top fraction: CSR, one column index per position and the
/// values of every stored channel at it (interleaved).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Sparse {
    /// Entries of row `i` are `row_ptr[i]..row_ptr[i+1]` (n + 1 values).
    pub row_ptr: Vec<u32>,
    /// Column of each position, increasing within a row.
    pub cols: Vec<u32>,
    /// `channels` values per position, already rounded to the stored
    /// precision (exactly representable in it, times the scale).
    pub values: Vec<f32>,
    /// Stored precision of the values.
    pub precision: SparseValues,
    /// For f16 values: the per-channel power of two the halves hold the
    /// values multiplied by (1 for f32).
    pub scale: [f32; 3],
}

impl Sparse {
    /// Positions stored.
    pub fn len(&self) -> usize {
        self.cols.len()
    }

    pub fn is_empty(&self) -> bool {
        self.cols.is_empty()
    }
}

/// Counts and time of one encoding: what was skipped, flushed or re-fitted.
#[derive(Clone, Debug, Default, Serialize, serde::Deserialize)]
pub struct EncodeStats {
    /// Wall-clock seconds of [`encode`].
    pub seconds: f64,
    /// Whether the three channels were equal and stored once.
    pub grey: bool,
    pub tiles_total: usize,
    pub tiles_stored: usize,
    /// Tiles skipped (all-zero dense part) over all tiles.
    pub tiles_skipped_fraction: f64,
    /// Positions in the sparse part.
    pub sparse_entries: usize,
    /// Share of `Σ |T|` (all channels) held exactly by the sparse part.
    pub sparse_mass_fraction: f64,
    /// Nonzero entries the dense format stores as 0 (below the log range,
    /// or below the smallest half).
    pub flushed_entries: u64,
    /// Blocks holding exact zeros among nonzero texels, encoded in the
    /// format's mode with an exact zero (BC1 3-colour, BC4 6-level).
    pub mixed_zero_blocks: u64,
    /// Entries that are exactly 0 but decode nonzero (texels zero in some
    /// channels only with BC1; zeros BC6H does not keep).
    pub zeros_lost: u64,
    /// Log formats: the factor each channel's scale was multiplied by so
    /// that the decoded dense part keeps the channel's sum (1 otherwise).
    pub mass_correction: [f64; 3],
}

/// A compressed transfer matrix (module doc).
#[derive(Clone, Debug, Serialize)]
pub struct Encoded {
    pub kind: CodecKind,
    /// Patches (the matrix is n × n).
    pub n: usize,
    /// Stored channels: 1 for a grey matrix (except BC6H, always RGB), else 3.
    pub channels: usize,
    pub format: DenseFormat,
    /// Side of the dense image: n, rounded up to a multiple of 4 for the
    /// block formats.
    pub image_size: usize,
    /// Log formats: the per-channel maximum `M_c` of the dense part. F16 and
    /// BC6H: the power of two the stored halves hold the values multiplied
    /// by. F32: 1.
    pub scale: [f32; 3],
    /// `L` of the log formats (0 otherwise).
    pub log_range: f32,
    pub index: TileIndex,
    /// The stored tiles' data (see [`TileIndex`]).
    #[serde(skip)]
    pub dense: Vec<u8>,
    pub sparse: Sparse,
    pub stats: EncodeStats,
}

impl Encoded {
    /// Bytes of the dense tiles.
    pub fn bytes_dense(&self) -> usize {
        self.dense.len()
    }

    /// Bytes of the sparse part: row pointers (u32), one column per
    /// position (u16 while n ≤ 65536, else u32), and the values.
    pub fn bytes_sparse(&self) -> usize {
        if self.sparse.is_empty() {
            return 0;
        }
        let col = if self.n <= 1 << 16 { 2 } else { 4 };
        let per_position = match self.sparse.precision {
            SparseValues::F32 => 4 * self.channels,
            SparseValues::F16 => 2 * self.channels,
            SparseValues::Rgb9e5 => 4,
        };
        self.sparse.row_ptr.len() * 4 + self.sparse.len() * (col + per_position)
    }

    /// Bytes of the tile index (row starts, tile columns and offsets) and of
    /// the header the decoder needs (scales and L: 16 bytes).
    pub fn bytes_index(&self) -> usize {
        self.index.row_start.len() * 4 + self.index.cols.len() * (2 + 4) + 16
    }

    pub fn bytes_total(&self) -> usize {
        self.bytes_dense() + self.bytes_sparse() + self.bytes_index()
    }

    /// All bytes per matrix entry, the three channels together:
    /// `bytes_total / n²` (module doc).
    pub fn bytes_per_entry(&self) -> f64 {
        if self.n == 0 {
            return 0.0;
        }
        self.bytes_total() as f64 / (self.n * self.n) as f64
    }

    /// The matrix as the run time sees it (see [`decode`]).
    pub fn decode(&self) -> [Vec<f32>; 3] {
        decode(self)
    }

    /// `H = T̃ · B0` per channel, computed from the compressed form as the
    /// run-time shader does: for each row of tiles, the stored tiles only
    /// (decoded block by block, accumulated in f32 in column order), then
    /// the sparse entries of each row. A grey matrix is decoded once and
    /// multiplied by the three channels of `B0`.
    pub fn gather(&self, b0: [&[f32]; 3]) -> [Vec<f32>; 3] {
        self.gather_in::<f32>(b0)
    }

    /// [`Encoded::gather`] accumulated in f64 (each product of two f32 is
    /// exact in f64), for error measures that must not see f32 summation:
    /// for F32 it equals [`mat_vec`] bit for bit (same order of terms).
    pub fn gather_f64(&self, b0: [&[f32]; 3]) -> [Vec<f64>; 3] {
        self.gather_in::<f64>(b0)
    }

    /// The gather with accumulators of type `A`.
    fn gather_in<A>(&self, b0: [&[f32]; 3]) -> [Vec<A>; 3]
    where
        A: Copy + Default + Send + std::ops::AddAssign + std::ops::Mul<Output = A> + From<f32>,
    {
        let n = self.n;
        for b in &b0 {
            assert_eq!(b.len(), n, "B0 must have one value per patch");
        }
        let book = self.codebook();
        let s = self.image_size;
        let tile = self.index.tile;
        let ch = self.channels;
        let per_row: Vec<Vec<[A; 3]>> = (0..self.index.tiles_per_side)
            .into_par_iter()
            .map(|tr| {
                let r0 = tr * tile;
                let h = tile.min(s - r0);
                let mut acc = vec![[A::default(); 3]; h];
                let mut buf = vec![0.0f32; tile * tile * ch];
                let (a, b) = (
                    self.index.row_start[tr] as usize,
                    self.index.row_start[tr + 1] as usize,
                );
                for slot in a..b {
                    let c0 = self.index.cols[slot] as usize * tile;
                    let w = tile.min(s - c0);
                    self.decode_tile(&book, slot, h, w, &mut buf);
                    for (r, acc_r) in acc.iter_mut().enumerate() {
                        if r0 + r >= n {
                            break;
                        }
                        for c in 0..w.min(n.saturating_sub(c0)) {
                            let v = &buf[(r * w + c) * ch..(r * w + c + 1) * ch];
                            for (oc, out) in acc_r.iter_mut().enumerate() {
                                *out += A::from(v[oc.min(ch - 1)]) * A::from(b0[oc][c0 + c]);
                            }
                        }
                    }
                }
                acc
            })
            .collect();
        let mut h: [Vec<A>; 3] = std::array::from_fn(|_| vec![A::default(); n]);
        for (tr, acc) in per_row.iter().enumerate() {
            for (r, v) in acc.iter().enumerate() {
                let i = tr * tile + r;
                if i < n {
                    for oc in 0..3 {
                        h[oc][i] = v[oc];
                    }
                }
            }
        }
        let sp = &self.sparse;
        if !sp.is_empty() {
            let sch = self.channels;
            for (i, window) in sp.row_ptr.windows(2).enumerate() {
                for e in window[0] as usize..window[1] as usize {
                    let j = sp.cols[e] as usize;
                    for (oc, hc) in h.iter_mut().enumerate() {
                        hc[i] += A::from(sp.values[e * sch + oc.min(sch - 1)]) * A::from(b0[oc][j]);
                    }
                }
            }
        }
        h
    }

    /// Checks the internal consistency of an encoding (for one read back
    /// from a file): sizes, index ranges and offsets, so that decoding
    /// cannot index out of bounds. A message names the first problem.
    pub fn check(&self) -> Result<(), BakeError> {
        let bad = |m: String| {
            Err(BakeError::Stage {
                stage: STAGE,
                message: format!("invalid encoded matrix: {m}"),
            })
        };
        let n = self.n;
        // The limits `encode` enforces, so that no size derived from a
        // file can overflow or ask for an absurd allocation.
        if n.checked_mul(n).is_none_or(|nn| nn > u32::MAX as usize) {
            return bad(format!("{n} patches exceed the codec's limits (n² < 2^32)"));
        }
        if self.index.tile > MAX_TILE {
            return bad(format!("tile edge {} exceeds {MAX_TILE}", self.index.tile));
        }
        let rgb_only = matches!(self.format, DenseFormat::Bc1 | DenseFormat::Bc6h);
        if !matches!(self.channels, 1 | 3) || (rgb_only && self.channels != 3) {
            return bad(format!(
                "{} channels with format {:?}",
                self.channels, self.format
            ));
        }
        let expect = if self.format.is_block() {
            n.div_ceil(4) * 4
        } else {
            n
        };
        if self.image_size != expect || self.index.tile == 0 || !self.index.tile.is_multiple_of(4) {
            return bad(format!(
                "image size {} / tile {} for n = {n}",
                self.image_size, self.index.tile
            ));
        }
        let tps = self.image_size.div_ceil(self.index.tile);
        let ix = &self.index;
        if ix.tiles_per_side != tps
            || ix.row_start.len() != tps + 1
            || ix.row_start.first() != Some(&0)
            || ix.row_start.windows(2).any(|w| w[0] > w[1])
            || *ix.row_start.last().unwrap() as usize != ix.cols.len()
            || ix.offsets.len() != ix.cols.len()
        {
            return bad("tile index sizes".into());
        }
        for tr in 0..tps {
            let (a, b) = (ix.row_start[tr] as usize, ix.row_start[tr + 1] as usize);
            if ix.cols[a..b].windows(2).any(|w| w[0] >= w[1])
                || ix.cols[a..b].iter().any(|&c| c as usize >= tps)
            {
                return bad(format!("tile columns of tile row {tr}"));
            }
            let h = ix.tile.min(self.image_size - tr * ix.tile);
            for slot in a..b {
                let w = ix
                    .tile
                    .min(self.image_size - ix.cols[slot] as usize * ix.tile);
                let end = ix.offsets[slot] as usize + self.format.tile_bytes(h, w, self.channels);
                if end > self.dense.len() {
                    return bad(format!(
                        "tile {slot} ends at byte {end} of {}",
                        self.dense.len()
                    ));
                }
            }
        }
        let sp = &self.sparse;
        let has_sparse = !sp.is_empty() || !sp.row_ptr.is_empty();
        if has_sparse
            && (sp.row_ptr.len() != n + 1
                || sp.row_ptr[0] != 0
                || sp.row_ptr.windows(2).any(|w| w[0] > w[1])
                || *sp.row_ptr.last().unwrap() as usize != sp.cols.len()
                || sp.values.len() != sp.cols.len() * self.channels
                || sp.cols.iter().any(|&c| c as usize >= n))
        {
            return bad("sparse part sizes or columns".into());
        }
        if self.scale.iter().any(|s| !s.is_finite()) || !self.log_range.is_finite() {
            return bad("non-finite scale".into());
        }
        Ok(())
    }

    /// The tables and scales the decoder needs.
    fn codebook(&self) -> Codebook {
        let mut lut = [[0.0f32; 256]; 3];
        let mut inv_scale = [1.0f32; 3];
        for c in 0..3 {
            match self.format {
                DenseFormat::Bc1 | DenseFormat::Bc4 => {
                    lut[c] = log_lut(self.scale[c], self.log_range);
                }
                DenseFormat::Bc6h | DenseFormat::F16 => inv_scale[c] = 1.0 / self.scale[c],
                DenseFormat::F32 => {}
            }
        }
        Codebook {
            format: self.format,
            channels: self.channels,
            lut,
            max: self.scale,
            log_range: self.log_range,
            inv_scale,
        }
    }

    /// Decodes stored tile `slot` (h × w texels) into `out` (texel-major,
    /// `channels` values per texel).
    fn decode_tile(&self, book: &Codebook, slot: usize, h: usize, w: usize, out: &mut [f32]) {
        let start = self.index.offsets[slot] as usize;
        let len = self.format.tile_bytes(h, w, self.channels);
        decode_tile_bytes(book, &self.dense[start..start + len], h, w, out);
    }
}

/// What decoding a tile needs.
struct Codebook {
    format: DenseFormat,
    channels: usize,
    /// BC1: value of each byte per channel.
    lut: [[f32; 256]; 3],
    /// BC4: the maxima `M_c`.
    max: [f32; 3],
    log_range: f32,
    /// F16 and BC6H: 1 / scale (a power of two, exact).
    inv_scale: [f32; 3],
}

/// The value of each log byte: 0 for byte 0, `M · e^{L (q/255 − 1)}` else.
fn log_lut(max: f32, log_range: f32) -> [f32; 256] {
    let mut lut = [0.0f32; 256];
    for (q, v) in lut.iter_mut().enumerate().skip(1) {
        *v = (max as f64 * (log_range as f64 * (q as f64 / 255.0 - 1.0)).exp()) as f32;
    }
    lut
}

/// The value of a BC4 texel decoded at float precision `x ∈ [0, 1]`.
fn log_value(x: f32, max: f32, log_range: f32) -> f32 {
    if x <= 0.0 {
        0.0
    } else {
        max * (log_range * (x - 1.0)).exp()
    }
}

/// Decodes one tile's bytes into values (texel-major, `channels` per texel).
fn decode_tile_bytes(book: &Codebook, bytes: &[u8], h: usize, w: usize, out: &mut [f32]) {
    let ch = book.channels;
    let (bh, bw) = (h / 4, w / 4);
    match book.format {
        DenseFormat::Bc1 => {
            let mut rgba = [0u8; 64];
            for by in 0..bh {
                for bx in 0..bw {
                    let k = by * bw + bx;
                    bcdec_rs::bc1(&bytes[k * 8..k * 8 + 8], &mut rgba, 16);
                    for y in 0..4 {
                        for x in 0..4 {
                            let t = ((by * 4 + y) * w + bx * 4 + x) * 3;
                            let p = (y * 4 + x) * 4;
                            for c in 0..3 {
                                out[t + c] = book.lut[c][rgba[p + c] as usize];
                            }
                        }
                    }
                }
            }
        }
        DenseFormat::Bc4 => {
            let plane = bh * bw * 8;
            let mut vals = [0.0f32; 16];
            for c in 0..ch {
                for by in 0..bh {
                    for bx in 0..bw {
                        let k = c * plane + (by * bw + bx) * 8;
                        bcdec_rs::bc4_float(&bytes[k..k + 8], &mut vals, 4, false);
                        for y in 0..4 {
                            for x in 0..4 {
                                let t = ((by * 4 + y) * w + bx * 4 + x) * ch + c;
                                out[t] = log_value(vals[y * 4 + x], book.max[c], book.log_range);
                            }
                        }
                    }
                }
            }
        }
        DenseFormat::Bc6h => {
            let mut halves = [0u16; 48];
            for by in 0..bh {
                for bx in 0..bw {
                    let k = (by * bw + bx) * 16;
                    bcdec_rs::bc6h_half(&bytes[k..k + 16], &mut halves, 12, false);
                    for y in 0..4 {
                        for x in 0..4 {
                            let t = ((by * 4 + y) * w + bx * 4 + x) * 3;
                            for c in 0..3 {
                                out[t + c] = f16::from_bits(halves[(y * 4 + x) * 3 + c]).to_f32()
                                    * book.inv_scale[c];
                            }
                        }
                    }
                }
            }
        }
        DenseFormat::F16 => {
            for (k, v) in out[..h * w * ch].iter_mut().enumerate() {
                let bits = u16::from_le_bytes([bytes[2 * k], bytes[2 * k + 1]]);
                *v = f16::from_bits(bits).to_f32() * book.inv_scale[k % ch];
            }
        }
        DenseFormat::F32 => {
            for (k, v) in out[..h * w * ch].iter_mut().enumerate() {
                *v = f32::from_le_bytes(bytes[4 * k..4 * k + 4].try_into().unwrap());
            }
        }
    }
}

/// The matrix as the run time sees it: dense tiles decoded (skipped tiles
/// are zero) plus the sparse part, three channels (a grey matrix's one
/// channel three times).
pub fn decode(e: &Encoded) -> [Vec<f32>; 3] {
    let n = e.n;
    let s = e.image_size;
    let tile = e.index.tile;
    let ch = e.channels;
    let book = e.codebook();
    let mut out: Vec<Vec<f32>> = (0..ch).map(|_| vec![0.0f32; n * n]).collect();
    // Rows of tiles in parallel: each owns a band of rows of the output.
    let bands: Vec<Vec<Vec<f32>>> = (0..e.index.tiles_per_side)
        .into_par_iter()
        .map(|tr| {
            let r0 = tr * tile;
            let rows = tile.min(n.saturating_sub(r0));
            let h = tile.min(s - r0);
            let mut band: Vec<Vec<f32>> = (0..ch).map(|_| vec![0.0f32; rows * n]).collect();
            let mut buf = vec![0.0f32; tile * tile * ch];
            for slot in e.index.row_start[tr] as usize..e.index.row_start[tr + 1] as usize {
                let c0 = e.index.cols[slot] as usize * tile;
                let w = tile.min(s - c0);
                e.decode_tile(&book, slot, h, w, &mut buf);
                for r in 0..rows {
                    for c in 0..w.min(n.saturating_sub(c0)) {
                        for (k, b) in band.iter_mut().enumerate() {
                            b[r * n + c0 + c] = buf[(r * w + c) * ch + k];
                        }
                    }
                }
            }
            band
        })
        .collect();
    for (tr, band) in bands.into_iter().enumerate() {
        let r0 = tr * tile;
        for (k, b) in band.into_iter().enumerate() {
            out[k][r0 * n..r0 * n + b.len()].copy_from_slice(&b);
        }
    }
    let sp = &e.sparse;
    for (i, window) in sp.row_ptr.windows(2).enumerate() {
        for p in window[0] as usize..window[1] as usize {
            let j = sp.cols[p] as usize;
            for (k, o) in out.iter_mut().enumerate() {
                // The dense texel at a sparse position decodes to exactly 0.
                o[i * n + j] += sp.values[p * ch + k];
            }
        }
    }
    if ch == 1 {
        let m = out.pop().unwrap();
        [m.clone(), m.clone(), m]
    } else {
        let mut it = out.into_iter();
        [it.next().unwrap(), it.next().unwrap(), it.next().unwrap()]
    }
}

/// The power of two `s` with `max · s ∈ [2^14, 2^15)`: halves of values
/// times `s` stay below 65504 and normal down to `2^−29 · max`. 1 for 0.
/// OpenGL's shared-exponent format `GL_RGB9_E5`, as specified by
/// EXT_texture_shared_exponent (section "Encoding of shared exponent
/// formats"): N = 9 mantissa bits, exponent bias B = 15, E_max = 31; bits
/// 0–8 red, 9–17 green, 18–26 blue, 27–31 the exponent.
pub mod rgb9e5 {
    const N: i32 = 9;
    const B: i32 = 15;
    const E_MAX: i32 = 31;

    /// The largest representable value, (2^N − 1) / 2^N · 2^(E_max − B).
    pub const MAX: f32 = 65408.0;

    /// Packs three values (negative and NaN are taken as 0, values above
    /// [`MAX`] as [`MAX`]) with the specification's rounding.
    pub fn pack(v: [f32; 3]) -> u32 {
        let c = v.map(|x| if x > 0.0 { x.min(MAX) as f64 } else { 0.0 });
        let max_c = c[0].max(c[1]).max(c[2]);
        // exp_shared' = max(−B − 1, floor(log2(max_c))) + 1 + B; a zero
        // triple takes the smallest exponent.
        let floor_log2 = if max_c > 0.0 {
            max_c.log2().floor() as i32
        } else {
            -B - 1
        };
        let mut e = floor_log2.max(-B - 1) + 1 + B;
        let step = |e: i32| 2f64.powi(e - B - N);
        let max_s = (max_c / step(e) + 0.5).floor() as i32;
        if max_s == 1 << N {
            e += 1;
        }
        debug_assert!((0..=E_MAX).contains(&e));
        let m = c.map(|x| ((x / step(e) + 0.5).floor() as u32).min((1 << N) - 1));
        m[0] | m[1] << 9 | m[2] << 18 | (e as u32) << 27
    }

    /// The three values of a packed word: `mantissa · 2^(e − B − N)`.
    pub fn unpack(p: u32) -> [f32; 3] {
        let e = (p >> 27) as i32;
        let step = 2f64.powi(e - B - N);
        [0, 9, 18].map(|s| (((p >> s) & 0x1ff) as f64 * step) as f32)
    }
}

fn pow2_scale(max: f32) -> f32 {
    if !(max > 0.0) {
        return 1.0;
    }
    let e = (max as f64).log2().floor() as i32;
    2f64.powi((14 - e).clamp(-100, 100)) as f32
}

/// The log byte of a dense value `v ≥ 0` for maximum `m` and range `l`.
fn log_byte(v: f32, m: f32, l: f32) -> u8 {
    if !(v > 0.0) || !(m > 0.0) {
        return 0;
    }
    let x = 255.0 / l as f64 * ((v as f64 / m as f64).ln() + l as f64);
    x.round().clamp(0.0, 255.0) as u8
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
        let mut sample: Vec<f32> = (0..total)
            .step_by(stride)
            .map(|k| dense(c, k / n, k % n))
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

/// Checks sizes and values: every entry finite and non-negative.
fn check_matrix(t: [&[f32]; 3], n: usize) -> Result<(), BakeError> {
    for (c, ch) in t.iter().enumerate() {
        if ch.len() != n * n {
            return Err(BakeError::Options(format!(
                "transfer channel {c} has {} entries, expected n² = {}",
                ch.len(),
                n * n
            )));
        }
        let bad = |v: &f32| !(v.is_finite() && *v >= 0.0);
        let row = ch
            .par_chunks(n.max(1))
            .position_first(|r| r.iter().any(bad));
        if let Some(p) = row.and_then(|i| {
            ch[i * n..(i + 1) * n]
                .iter()
                .position(bad)
                .map(|j| i * n + j)
        }) {
            return Err(BakeError::Stage {
                stage: STAGE,
                message: format!(
                    "transfer entry ({}, {}) of channel {c} is {}: entries must be finite and \
                     non-negative",
                    p / n,
                    p % n,
                    ch[p]
                ),
            });
        }
    }
    Ok(())
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

/// The sparse ranking key of an entry: `Σ_c t_c / max_c` (f32, fixed
/// order), as its bit pattern (monotonic for non-negative floats).
fn sparse_key(channels: &[&[f32]], inv_max: &[f32], k: usize) -> u32 {
    let mut s = 0.0f32;
    for (ch, &im) in channels.iter().zip(inv_max) {
        s += ch[k] * im;
    }
    s.to_bits()
}

/// Selects the top `count` positions by [`sparse_key`] (ties in row-major
/// order) without sorting or storing all keys: a two-level radix select on
/// the keys' bit patterns (high 16 bits, then low 16), then one pass that
/// collects the positions row by row. Returns the CSR rows' columns.
fn select_top(channels: &[&[f32]], n: usize, count: usize) -> Vec<Vec<u32>> {
    if count == 0 || n == 0 {
        return vec![Vec::new(); n];
    }
    let inv_max: Vec<f32> = channels
        .iter()
        .map(|ch| {
            let m = ch.par_iter().cloned().reduce(|| 0.0f32, f32::max);
            if m > 0.0 {
                1.0 / m
            } else {
                0.0
            }
        })
        .collect();
    let key = |k: usize| sparse_key(channels, &inv_max, k);
    let histogram = |select: &(dyn Fn(u32) -> Option<usize> + Sync)| -> Vec<u64> {
        (0..n)
            .into_par_iter()
            .fold(
                || vec![0u64; 1 << 16],
                |mut h, i| {
                    for k in i * n..(i + 1) * n {
                        if let Some(b) = select(key(k)) {
                            h[b] += 1;
                        }
                    }
                    h
                },
            )
            .reduce(
                || vec![0u64; 1 << 16],
                |mut a, b| {
                    for (x, y) in a.iter_mut().zip(b) {
                        *x += y;
                    }
                    a
                },
            )
    };
    // Keys of zero entries are 0 and never selected.
    let count = count as u64;
    let high = histogram(&|b| (b != 0).then_some((b >> 16) as usize));
    let nonzero: u64 = high.iter().sum();
    let count = count.min(nonzero);
    if count == 0 {
        return vec![Vec::new(); n];
    }
    // The bucket where the running count from the top reaches `count`.
    let (mut above, mut hb) = (0u64, 0usize);
    for b in (0..1 << 16).rev() {
        if above + high[b] >= count {
            hb = b;
            break;
        }
        above += high[b];
    }
    let low = histogram(&|b| (b != 0 && (b >> 16) as usize == hb).then_some((b & 0xffff) as usize));
    let mut lb = 0usize;
    for b in (0..1 << 16).rev() {
        if above + low[b] >= count {
            lb = b;
            break;
        }
        above += low[b];
    }
    let threshold = ((hb as u32) << 16) | lb as u32;
    // `above` keys are > threshold; `count − above` ties are taken in
    // row-major order.
    let ties_wanted = count - above;
    let ties_per_row: Vec<u64> = (0..n)
        .into_par_iter()
        .map(|i| {
            (i * n..(i + 1) * n)
                .filter(|&k| key(k) == threshold)
                .count() as u64
        })
        .collect();
    let mut ties_allowed = vec![0u64; n];
    let mut left = ties_wanted;
    for i in 0..n {
        let t = ties_per_row[i].min(left);
        ties_allowed[i] = t;
        left -= t;
    }
    (0..n)
        .into_par_iter()
        .map(|i| {
            let mut ties = ties_allowed[i];
            let mut cols = Vec::new();
            for j in 0..n {
                let b = key(i * n + j);
                if b > threshold || (b == threshold && ties > 0) {
                    if b == threshold {
                        ties -= 1;
                    }
                    cols.push(j as u32);
                }
            }
            cols
        })
        .collect()
}

/// Per-tile counts gathered while encoding.
#[derive(Clone, Copy, Default)]
struct TileCounts {
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
pub fn encode(kind: CodecKind, t: [&[f32]; 3], n: usize) -> Result<Encoded, BakeError> {
    let start = Instant::now();
    kind.validate()?;
    check_matrix(t, n)?;
    if n > (u16::MAX as usize + 1) * TILE || n * n > u32::MAX as usize {
        return Err(BakeError::Options(format!(
            "{n} patches exceed the codec's limits (n² < 2^32)"
        )));
    }
    let distinct = reorder::distinct_channels(t);
    let grey = distinct.len() == 1;
    let format = DenseFormat::of(kind, distinct.len());
    // BC6H always stores RGB; the others store the distinct channels.
    let stored: Vec<&[f32]> = if format == DenseFormat::Bc6h {
        t.to_vec()
    } else {
        distinct.clone()
    };
    let ch = stored.len();

    // The sparse part (log formats).
    let (top_fraction, log_range, sparse_values) =
        kind.log_params().unwrap_or((0.0, 0.0, SparseValues::F32));
    let count = (top_fraction * (n * n) as f64).round() as usize;
    let rows = select_top(&stored, n, count);
    let mut mask = Mask {
        bits: vec![0u64; (n * n).div_ceil(64)],
        n,
    };
    let mut row_ptr = Vec::with_capacity(n + 1);
    row_ptr.push(0u32);
    let mut cols = Vec::new();
    for (i, r) in rows.iter().enumerate() {
        for &j in r {
            let k = i * n + j as usize;
            mask.bits[k / 64] |= 1 << (k % 64);
            cols.push(j);
        }
        row_ptr.push(cols.len() as u32);
    }
    drop(rows);
    let mut values = Vec::with_capacity(cols.len() * ch);
    for (i, w) in row_ptr.windows(2).enumerate() {
        for &j in &cols[w[0] as usize..w[1] as usize] {
            for c in &stored {
                values.push(c[i * n + j as usize]);
            }
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
    let (sparse_mass, total_mass) = {
        let total: f64 = stored
            .iter()
            .map(|c| c.par_iter().map(|&v| v as f64).sum::<f64>())
            .sum();
        let sparse: f64 = values.iter().map(|&v| v as f64).sum();
        (sparse, total)
    };
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
        let m = (0..n)
            .into_par_iter()
            .map(|i| (0..n).map(|j| dense_value(c, i, j)).fold(0.0f32, f32::max))
            .reduce(|| 0.0f32, f32::max);
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
    let tiles: Vec<(Option<Vec<u8>>, TileCounts)> = (0..tps * tps)
        .into_par_iter()
        .map(|k| {
            let (tr, tc) = (k / tps, k % tps);
            let (r0, c0) = (tr * TILE, tc * TILE);
            let (h, w) = (TILE.min(image_size - r0), TILE.min(image_size - c0));
            let mut vals = vec![0.0f32; h * w * ch];
            for r in 0..h {
                for c in 0..w {
                    for k in 0..ch {
                        vals[(r * w + c) * ch + k] = dense_value(k, r0 + r, c0 + c);
                    }
                }
            }
            encode_tile(&book, &vals, h, w, &scale)
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
        return Err(BakeError::Options(format!(
            "the dense part takes {} bytes, more than the 4 GiB its u32 offsets address",
            dense.len()
        )));
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
        stats,
    })
}

/// Encodes one tile of dense values (texel-major, `channels` per texel);
/// the bytes are `None` when the tile stores nothing (every stored value
/// would be 0). Also decodes the result to count zeros the format did not
/// keep.
fn encode_tile(
    book: &Codebook,
    vals: &[f32],
    h: usize,
    w: usize,
    scale: &[f32; 3],
) -> (Option<Vec<u8>>, TileCounts) {
    let ch = book.channels;
    let mut counts = TileCounts::default();
    let bytes = match book.format {
        DenseFormat::Bc1 | DenseFormat::Bc4 => {
            let q: Vec<u8> = vals
                .iter()
                .enumerate()
                .map(|(k, &v)| log_byte(v, scale[k % ch], book.log_range))
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

/// The texels (flat indices into the tile) of block (by, bx).
fn block_texels(by: usize, bx: usize, w: usize) -> [usize; 16] {
    std::array::from_fn(|p| (by * 4 + p / 4) * w + bx * 4 + p % 4)
}

/// BC1 of one tile of RGB log bytes, keeping black texels exactly black
/// (module doc): all-black blocks become all-zero blocks; mixed blocks are
/// encoded with their black texels replaced by the mean of the others, then
/// rewritten in 3-colour mode.
fn encode_bc1_tile(q: &[u8], h: usize, w: usize, counts: &mut TileCounts) -> Vec<u8> {
    let (bh, bw) = (h / 4, w / 4);
    let mut rgba = vec![255u8; h * w * 4];
    for (t, px) in q.chunks(3).enumerate() {
        rgba[t * 4..t * 4 + 3].copy_from_slice(px);
    }
    let is_black = |t: usize| q[t * 3] == 0 && q[t * 3 + 1] == 0 && q[t * 3 + 2] == 0;
    // Mean fill of the black texels of mixed blocks.
    let mut kinds = vec![0u8; bh * bw]; // 0: no black, 1: mixed, 2: all black
    for by in 0..bh {
        for bx in 0..bw {
            let texels = block_texels(by, bx, w);
            let blacks = texels.iter().filter(|&&t| is_black(t)).count();
            kinds[by * bw + bx] = match blacks {
                0 => 0,
                16 => 2,
                _ => 1,
            };
            if blacks > 0 && blacks < 16 {
                let mut sum = [0u32; 3];
                for &t in texels.iter().filter(|&&t| !is_black(t)) {
                    for c in 0..3 {
                        sum[c] += q[t * 3 + c] as u32;
                    }
                }
                let k = (16 - blacks) as u32;
                let mean = sum.map(|s| ((s + k / 2) / k) as u8);
                for &t in texels.iter().filter(|&&t| is_black(t)) {
                    rgba[t * 4..t * 4 + 3].copy_from_slice(&mean);
                }
            }
        }
    }
    let surface = intel_tex_2::RgbaSurface {
        data: &rgba,
        width: w as u32,
        height: h as u32,
        stride: (w * 4) as u32,
    };
    let mut blocks = intel_tex_2::bc1::compress_blocks(&surface);
    for (b, &kind) in kinds.iter().enumerate() {
        let block = &mut blocks[b * 8..b * 8 + 8];
        match kind {
            2 => block.fill(0),
            1 => {
                counts.mixed += 1;
                let texels = block_texels(b / bw, b % bw, w);
                let src: [[u8; 3]; 16] =
                    std::array::from_fn(|p| std::array::from_fn(|c| q[texels[p] * 3 + c]));
                let fixed = bc1_three_colour(block.try_into().unwrap(), &src);
                block.copy_from_slice(&fixed);
            }
            _ => {
                let texels = block_texels(b / bw, b % bw, w);
                let src: [[u8; 3]; 16] =
                    std::array::from_fn(|p| std::array::from_fn(|c| q[texels[p] * 3 + c]));
                let fixed = bc1_four_colour(block.try_into().unwrap(), &src);
                block.copy_from_slice(&fixed);
            }
        }
    }
    blocks
}

/// A 4-colour-mode BC1 block for `src` (no black texels to keep) with
/// endpoints `a`, `b`: ordered `c0 > c1`, each texel at the nearest palette
/// colour (ties to the lower index). Equal endpoints give a one-colour
/// block (all indices 0, which is `c0` in either mode). Returns the block,
/// its indices and its squared error.
fn bc1_build4(a: u16, b: u16, src: &[[u8; 3]; 16]) -> ([u8; 8], [u8; 16], u64) {
    let (c0, c1) = (a.max(b), a.min(b));
    let pal = bc1_palette(c0, c1);
    let mut idx = [0u8; 16];
    let mut sse = 0u64;
    for (p, px) in src.iter().enumerate() {
        let err = |k: usize| -> u64 {
            (0..3)
                .map(|c| (px[c] as i64 - pal[k][c] as i64).pow(2) as u64)
                .sum()
        };
        let best = if c0 == c1 {
            0
        } else {
            (0..4).min_by_key(|&k| (err(k), k)).unwrap()
        };
        idx[p] = best as u8;
        sse += err(best);
    }
    (pack_bc1(c0, c1, &idx), idx, sse)
}

/// The encoder's block for a block without black texels, made safe and
/// refined: the encoder occasionally emits `c0 ≤ c1` (3-colour mode, whose
/// index 3 is black), so the block is rebuilt in 4-colour mode with its
/// endpoints; then up to two least-squares refits of the endpoints for the
/// palette `c0, c1, (2c0 + c1)/3, (c0 + 2c1)/3` given the indices, each
/// kept only if the block's squared error drops. Rounding the refitted
/// endpoints to the nearest 5:6:5 value also removes most of the encoder's
/// systematic bias (about −0.3 of a byte level in G and B on smooth data).
fn bc1_four_colour(ispc: [u8; 8], src: &[[u8; 3]; 16]) -> [u8; 8] {
    let e0 = u16::from_le_bytes([ispc[0], ispc[1]]);
    let e1 = u16::from_le_bytes([ispc[2], ispc[3]]);
    let (mut best, mut idx, mut sse) = bc1_build4(e0, e1, src);
    let weights = |k: u8| match k {
        0 => (1.0, 0.0),
        1 => (0.0, 1.0),
        2 => (2.0 / 3.0, 1.0 / 3.0),
        _ => (1.0 / 3.0, 2.0 / 3.0),
    };
    for _ in 0..2 {
        if sse == 0 {
            break;
        }
        let Some((c0, c1)) = least_squares_endpoints(src, &idx, weights, |_| true) else {
            break;
        };
        let (block, new_idx, new_sse) = bc1_build4(to_565(c0), to_565(c1), src);
        if new_sse < sse {
            best = block;
            idx = new_idx;
            sse = new_sse;
        } else {
            break;
        }
    }
    best
}

/// Least-squares endpoints `(c0, c1)` (byte units, per channel) for the
/// texels of `src` that `used` accepts, given their indices and the weights
/// `(w0, w1)` of each index: minimises `Σ |x − (w0 c0 + w1 c1)|²`. When the
/// system is singular (one palette colour for every texel) both endpoints
/// are the mean; `None` when no texel is used.
fn least_squares_endpoints(
    src: &[[u8; 3]; 16],
    idx: &[u8; 16],
    weights: impl Fn(u8) -> (f64, f64),
    used: impl Fn(u8) -> bool,
) -> Option<([f64; 3], [f64; 3])> {
    let (mut aa, mut ab, mut bb) = (0.0f64, 0.0f64, 0.0f64);
    let (mut ax, mut bx, mut sum) = ([0.0f64; 3], [0.0f64; 3], [0.0f64; 3]);
    let mut count = 0usize;
    for (p, px) in src.iter().enumerate() {
        if !used(idx[p]) {
            continue;
        }
        let (a, b) = weights(idx[p]);
        aa += a * a;
        ab += a * b;
        bb += b * b;
        count += 1;
        for c in 0..3 {
            ax[c] += a * px[c] as f64;
            bx[c] += b * px[c] as f64;
            sum[c] += px[c] as f64;
        }
    }
    if count == 0 {
        return None;
    }
    let det = aa * bb - ab * ab;
    if det.abs() > 1e-9 {
        Some((
            std::array::from_fn(|c| (bb * ax[c] - ab * bx[c]) / det),
            std::array::from_fn(|c| (aa * bx[c] - ab * ax[c]) / det),
        ))
    } else {
        let m = sum.map(|v| v / count as f64);
        Some((m, m))
    }
}

/// The 4 palette colours of a BC1 block with endpoints `c0`, `c1`, as
/// `bcdec_rs` decodes them.
fn bc1_palette(c0: u16, c1: u16) -> [[u8; 3]; 4] {
    let mut block = [0u8; 8];
    block[0..2].copy_from_slice(&c0.to_le_bytes());
    block[2..4].copy_from_slice(&c1.to_le_bytes());
    // Texels 0..3 take indices 0..3.
    block[4] = 0b1110_0100;
    let mut rgba = [0u8; 64];
    bcdec_rs::bc1(&block, &mut rgba, 16);
    std::array::from_fn(|k| [rgba[k * 4], rgba[k * 4 + 1], rgba[k * 4 + 2]])
}

/// A 3-colour-mode BC1 block for `src` with endpoints `a`, `b` (ordered so
/// that `c0 ≤ c1`): black texels take index 3 (exact black), the others the
/// nearest palette colour (black included, ties to the lower index).
/// Returns the block, its indices and its squared error.
fn bc1_build3(a: u16, b: u16, src: &[[u8; 3]; 16]) -> ([u8; 8], [u8; 16], u64) {
    let (c0, c1) = (a.min(b), a.max(b));
    let pal = bc1_palette(c0, c1);
    debug_assert_eq!(pal[3], [0, 0, 0]);
    let mut idx = [0u8; 16];
    let mut sse = 0u64;
    for (p, px) in src.iter().enumerate() {
        if *px == [0, 0, 0] {
            idx[p] = 3;
            continue;
        }
        let err = |k: usize| -> u64 {
            (0..3)
                .map(|c| (px[c] as i64 - pal[k][c] as i64).pow(2) as u64)
                .sum()
        };
        let best = (0..4).min_by_key(|&k| (err(k), k)).unwrap();
        idx[p] = best as u8;
        sse += err(best);
    }
    (pack_bc1(c0, c1, &idx), idx, sse)
}

/// A BC1 block: the two RGB565 endpoints, then 2-bit indices, texel 0 in
/// the lowest bits (the S3TC layout).
fn pack_bc1(c0: u16, c1: u16, idx: &[u8; 16]) -> [u8; 8] {
    let mut block = [0u8; 8];
    block[0..2].copy_from_slice(&c0.to_le_bytes());
    block[2..4].copy_from_slice(&c1.to_le_bytes());
    let bits = idx
        .iter()
        .enumerate()
        .fold(0u32, |acc, (p, &k)| acc | (k as u32) << (2 * p));
    block[4..8].copy_from_slice(&bits.to_le_bytes());
    block
}

/// Packs an RGB colour in [0, 255] (f64) to RGB565, rounding.
fn to_565(c: [f64; 3]) -> u16 {
    let r = (c[0] * 31.0 / 255.0).round().clamp(0.0, 31.0) as u16;
    let g = (c[1] * 63.0 / 255.0).round().clamp(0.0, 63.0) as u16;
    let b = (c[2] * 31.0 / 255.0).round().clamp(0.0, 31.0) as u16;
    (r << 11) | (g << 5) | b
}

/// Rewrites a mixed block in BC1's 3-colour mode (module doc): the
/// encoder's endpoints reordered, then up to two least-squares refits of
/// the endpoints for the palette `c0, c1, (c0 + c1)/2` given the current
/// indices, each kept only if the block's squared error drops.
fn bc1_three_colour(ispc: [u8; 8], src: &[[u8; 3]; 16]) -> [u8; 8] {
    let e0 = u16::from_le_bytes([ispc[0], ispc[1]]);
    let e1 = u16::from_le_bytes([ispc[2], ispc[3]]);
    let (mut best, mut idx, mut sse) = bc1_build3(e0, e1, src);
    let weights = |k: u8| match k {
        0 => (1.0, 0.0),
        1 => (0.0, 1.0),
        _ => (0.5, 0.5),
    };
    for _ in 0..2 {
        if sse == 0 {
            break;
        }
        // Texels at index 3 (black) do not constrain the endpoints.
        let Some((c0, c1)) = least_squares_endpoints(src, &idx, weights, |k| k < 3) else {
            break;
        };
        let (block, new_idx, new_sse) = bc1_build3(to_565(c0), to_565(c1), src);
        if new_sse < sse {
            best = block;
            idx = new_idx;
            sse = new_sse;
        } else {
            break;
        }
    }
    best
}

/// BC4 of one tile, one plane per stored channel, keeping zero bytes
/// exactly zero: blocks whose zeros the encoder does not keep are rewritten
/// in 6-level mode (module doc).
fn encode_bc4_tile(q: &[u8], h: usize, w: usize, ch: usize, counts: &mut TileCounts) -> Vec<u8> {
    let (bh, bw) = (h / 4, w / 4);
    let mut out = Vec::with_capacity(ch * bh * bw * 8);
    let mut plane = vec![0u8; h * w];
    for c in 0..ch {
        for (t, v) in plane.iter_mut().enumerate() {
            *v = q[t * ch + c];
        }
        let surface = intel_tex_2::RSurface {
            data: &plane,
            width: w as u32,
            height: h as u32,
            stride: w as u32,
        };
        let mut blocks = intel_tex_2::bc4::compress_blocks(&surface);
        for b in 0..bh * bw {
            let texels = block_texels(b / bw, b % bw, w);
            let src: [u8; 16] = std::array::from_fn(|p| plane[texels[p]]);
            let block = &mut blocks[b * 8..b * 8 + 8];
            if src.iter().all(|&v| v == 0) {
                block.fill(0);
                continue;
            }
            if !src.contains(&0) {
                continue;
            }
            // Mixed: the encoder's block is kept only if it keeps the zeros
            // and beats the best 6-level block.
            counts.mixed += 1;
            let six = bc4_six_level(&src);
            let ispc: [u8; 8] = block.try_into().unwrap();
            let better = match (bc4_sse(&ispc, &src), bc4_sse(&six, &src)) {
                (Some(a), Some(b)) => a <= b,
                (Some(_), None) => true,
                _ => false,
            };
            if !better {
                block.copy_from_slice(&six);
            }
        }
        out.extend_from_slice(&blocks);
    }
    out
}

/// The squared error (in byte units) of a BC4 block against `src`, `None`
/// if a zero byte of `src` decodes nonzero.
fn bc4_sse(block: &[u8; 8], src: &[u8; 16]) -> Option<f64> {
    let mut dec = [0.0f32; 16];
    bcdec_rs::bc4_float(block, &mut dec, 4, false);
    let mut sse = 0.0f64;
    for (&s, &d) in src.iter().zip(&dec) {
        if s == 0 && d != 0.0 {
            return None;
        }
        sse += (d as f64 * 255.0 - s as f64).powi(2);
    }
    Some(sse)
}

/// A BC4 block in 6-level mode (`r0 ≤ r1`) for bytes with zeros: zeros at
/// index 6 (exactly 0), the others at the nearest of the 8 levels (ties to
/// the lower index); the endpoints are searched within ±2 of the smallest
/// and largest nonzero byte for the least squared error (ties to the first
/// found), so the result is deterministic.
fn bc4_six_level(src: &[u8; 16]) -> [u8; 8] {
    let nz = src.iter().filter(|&&v| v > 0);
    let lo = nz.clone().min().copied().unwrap_or(0) as i32;
    let hi = nz.max().copied().unwrap_or(0) as i32;
    let mut best = ([0u8; 8], f64::INFINITY);
    for r0 in (lo - 2).max(0)..=(lo + 2).min(255) {
        for r1 in (hi - 2).max(r0)..=(hi + 2).min(255) {
            let block = bc4_six_level_with(src, r0 as u8, r1 as u8);
            let sse = bc4_sse(&block, src).expect("6-level blocks keep zeros");
            if sse < best.1 {
                best = (block, sse);
            }
        }
    }
    best.0
}

/// The 6-level block with endpoints `r0 ≤ r1` and nearest-level indices.
fn bc4_six_level_with(src: &[u8; 16], r0: u8, r1: u8) -> [u8; 8] {
    let (a, b) = (r0 as f64, r1 as f64);
    let levels: [f64; 8] = [
        a,
        b,
        (4.0 * a + b) / 5.0,
        (3.0 * a + 2.0 * b) / 5.0,
        (2.0 * a + 3.0 * b) / 5.0,
        (a + 4.0 * b) / 5.0,
        0.0,
        255.0,
    ];
    let mut bits = 0u64;
    for (p, &v) in src.iter().enumerate() {
        let k = if v == 0 {
            6
        } else {
            (0..8)
                .min_by(|&x, &y| {
                    let (dx, dy) = ((levels[x] - v as f64).abs(), (levels[y] - v as f64).abs());
                    dx.partial_cmp(&dy).unwrap().then(x.cmp(&y))
                })
                .unwrap()
        };
        bits |= (k as u64) << (3 * p);
    }
    let mut block = [0u8; 8];
    block[0] = r0;
    block[1] = r1;
    block[2..8].copy_from_slice(&bits.to_le_bytes()[..6]);
    block
}

/// Errors of a decoded matrix against the original (DESIGN.md section 3,
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

/// The candidates [`choose`] tries by default: BC1-log with the automatic
/// log range and RGB9E5 sparse values at top fractions {0, 0.01, 0.02,
/// 0.03, 0.04, 0.06, 0.08}, the same at the top 4 % with f16 and f32 sparse
/// values, the thesis's setting, BC4-log at {0, 0.02}, BC6H, F16 and F32
/// (exact, so some candidate always passes).
pub fn default_candidates() -> Vec<CodecKind> {
    let bc1 = |top_fraction, sparse| CodecKind::Bc1Log {
        top_fraction,
        log_range: LOG_RANGE_AUTO,
        sparse,
    };
    let mut v: Vec<CodecKind> = [0.0, 0.01, 0.02, 0.03, 0.04, 0.06, 0.08]
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

/// The cheapest setting (total bytes) among `candidates` (empty: the
/// [`default_candidates`]) whose relative RMS error of `H = T̃ · B0` over
/// `b0_samples` is at most `max_error`: every candidate is encoded and
/// measured, ties go to the earlier candidate. Returns the setting, its
/// encoding and its measured error.
pub fn choose(
    t: [&[f32]; 3],
    n: usize,
    b0_samples: &[[Vec<f32>; 3]],
    max_error: f64,
    candidates: &[CodecKind],
) -> Result<(CodecKind, Encoded, f64), BakeError> {
    choose_with(t, n, b0_samples, max_error, candidates, &mut |_, _, _| {})
}

/// [`choose`], calling `on_candidate(setting, H error, bytes per entry)`
/// as each candidate is measured (for progress output and reports).
pub fn choose_with(
    t: [&[f32]; 3],
    n: usize,
    b0_samples: &[[Vec<f32>; 3]],
    max_error: f64,
    candidates: &[CodecKind],
    on_candidate: &mut dyn FnMut(CodecKind, f64, f64),
) -> Result<(CodecKind, Encoded, f64), BakeError> {
    if !(max_error >= 0.0) {
        return Err(BakeError::Options(format!(
            "--max-error must be a non-negative number, got {max_error}"
        )));
    }
    if b0_samples.is_empty() {
        return Err(BakeError::Options(
            "choosing a codec by error needs at least one B0 sample".into(),
        ));
    }
    for b0 in b0_samples {
        if b0.iter().any(|c| c.len() != n) {
            return Err(BakeError::Options(format!(
                "every B0 sample needs {n} values per channel"
            )));
        }
    }
    let defaults;
    let candidates = if candidates.is_empty() {
        defaults = default_candidates();
        &defaults[..]
    } else {
        candidates
    };
    // The exact H of every sample, once; each candidate is measured through
    // its f64 gather, without a decoded n × n copy.
    let reference: Vec<[Vec<f64>; 3]> = b0_samples
        .iter()
        .map(|b| std::array::from_fn(|c| mat_vec(t[c], n, &b[c])))
        .collect();
    let mut best: Option<(CodecKind, Encoded, f64)> = None;
    let mut tried = Vec::new();
    for &kind in candidates {
        let e = encode(kind, t, n)?;
        let err = h_error(&e, &reference, b0_samples);
        on_candidate(kind, err, e.bytes_per_entry());
        tried.push(format!(
            "{kind}: {err:.3e} at {:.3} B/entry",
            e.bytes_per_entry()
        ));
        if err <= max_error
            && best
                .as_ref()
                .is_none_or(|b| e.bytes_total() < b.1.bytes_total())
        {
            best = Some((kind, e, err));
        }
    }
    best.ok_or_else(|| {
        BakeError::Options(format!(
            "no codec reaches a relative H error of {max_error}; tried {}",
            tried.join("; ")
        ))
    })
}

/// The relative RMS error of `H̃ = T̃ B0` (computed from the encoding in
/// f64, [`Encoded::gather_f64`]) against the exact products `reference`
/// (`T B0` per sample and channel, e.g. from [`mat_vec`]), pooled over all
/// samples, channels and patches as in [`CodecError::rel_rms_h`].
pub fn h_error(e: &Encoded, reference: &[[Vec<f64>; 3]], b0_samples: &[[Vec<f32>; 3]]) -> f64 {
    let (mut d2, mut r2) = (0.0f64, 0.0f64);
    for (h, b0) in reference.iter().zip(b0_samples) {
        let g = e.gather_f64([&b0[0], &b0[1], &b0[2]]);
        for c in 0..3 {
            for (a, b) in h[c].iter().zip(&g[c]) {
                d2 += (b - a) * (b - a);
                r2 += a * a;
            }
        }
    }
    ratio(d2.sqrt(), r2.sqrt())
}

/// One line of the compression report.
#[derive(Clone, Debug, Serialize)]
pub struct ReportRow {
    pub reorder: String,
    pub reorder_seconds: f64,
    pub codec: String,
    pub error: CodecError,
    pub bytes_dense_per_entry: f64,
    pub bytes_sparse_per_entry: f64,
    pub bytes_index_per_entry: f64,
    pub bytes_per_entry: f64,
    pub encode_seconds: f64,
    pub tiles_skipped_fraction: f64,
    pub flushed_entries: u64,
    pub mixed_zero_blocks: u64,
    pub zeros_lost: u64,
}

/// Every reordering in `methods` times every codec in `kinds`: the
/// matrix and the B0 samples are permuted, encoded, decoded and measured
/// (the measures do not depend on the labelling).
pub fn report_rows(
    t: [&[f32]; 3],
    n: usize,
    patches: &[Patch],
    b0_samples: &[[Vec<f32>; 3]],
    methods: &[ReorderMethod],
    kinds: &[CodecKind],
    backend: Backend,
) -> Result<Vec<ReportRow>, BakeError> {
    let mut rows = Vec::new();
    let grey = reorder::distinct_channels(t).len() == 1;
    for &method in methods {
        // `Backend` is not `Copy`: a fresh value per reordering.
        let b = match &backend {
            Backend::Cpu => Backend::Cpu,
            Backend::OpenCl(g) => Backend::OpenCl(g),
        };
        let (perm, rstats) = reorder::reorder_with_stats(method, t, n, patches, b)?;
        let (tp, bp) = permute_problem(&perm, t, n, b0_samples, grey);
        let tref: [&[f32]; 3] = [&tp[0], &tp[1 % tp.len()], &tp[2 % tp.len()]];
        for &kind in kinds {
            let e = encode(kind, tref, n)?;
            let err = measure(tref, n, &e.decode(), &bp);
            let per = |b: usize| b as f64 / (n * n).max(1) as f64;
            rows.push(ReportRow {
                reorder: method.name(),
                reorder_seconds: rstats.seconds,
                codec: kind.name(),
                error: err,
                bytes_dense_per_entry: per(e.bytes_dense()),
                bytes_sparse_per_entry: per(e.bytes_sparse()),
                bytes_index_per_entry: per(e.bytes_index()),
                bytes_per_entry: e.bytes_per_entry(),
                encode_seconds: e.stats.seconds,
                tiles_skipped_fraction: e.stats.tiles_skipped_fraction,
                flushed_entries: e.stats.flushed_entries,
                mixed_zero_blocks: e.stats.mixed_zero_blocks,
                zeros_lost: e.stats.zeros_lost,
            });
        }
    }
    Ok(rows)
}

/// The matrix (distinct channels only when grey) and the B0 samples in the
/// order of `perm`.
fn permute_problem(
    perm: &Permutation,
    t: [&[f32]; 3],
    n: usize,
    b0_samples: &[[Vec<f32>; 3]],
    grey: bool,
) -> (Vec<Vec<f32>>, Vec<[Vec<f32>; 3]>) {
    let channels: &[&[f32]] = if grey { &t[..1] } else { &t[..] };
    let tp = channels
        .iter()
        .map(|c| perm.apply_symmetric(c, n))
        .collect();
    let bp = b0_samples
        .iter()
        .map(|b| std::array::from_fn(|c| perm.apply_vec(&b[c])))
        .collect();
    (tp, bp)
}

/// The report as a Markdown table: the thesis's entry errors (mean, max,
/// total), the relative Frobenius error of T̃, the relative RMS error of H
/// (and the worst sample), bytes per entry (dense, sparse, index, total),
/// reorder and encode times, and the skipped tiles.
pub fn report_table(rows: &[ReportRow]) -> String {
    let mut s = String::new();
    s.push_str(
        "| reorder | codec | mean abs | max abs | total abs | rel. Frob. T | rel. RMS H | worst H \
         | B/entry dense | sparse | index | total | reorder s | encode s | tiles skipped |\n",
    );
    s.push_str("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for r in rows {
        let _ = writeln!(
            s,
            "| {} | {} | {:.3e} | {:.3e} | {:.3e} | {:.3e} | {:.3e} | {:.3e} | {:.3} | {:.3} | \
             {:.4} | {:.3} | {:.2} | {:.2} | {:.1} % |",
            r.reorder,
            r.codec,
            r.error.mean_abs,
            r.error.max_abs,
            r.error.total_abs,
            r.error.rel_frobenius,
            r.error.rel_rms_h,
            r.error.max_rel_h,
            r.bytes_dense_per_entry,
            r.bytes_sparse_per_entry,
            r.bytes_index_per_entry,
            r.bytes_per_entry,
            r.reorder_seconds,
            r.encode_seconds,
            100.0 * r.tiles_skipped_fraction
        );
    }
    s
}

// ---------------------------------------------------------------------------
// Serialization into the bake file's codec sections

/// The codec sections of a bake file (`bakefile::CodecBlob`): how an
/// [`Encoded`] matrix is laid out in `CDSC`, `CPRM`, `SCAL`, `DENS`, `TIDX`
/// and `SPRS`. All integers are little-endian.
///
/// - `CDSC`: `kind` is the dense format ([`DenseFormat::code`]: 1 BC1,
///   2 BC4, 3 BC6H, 4 F16, 5 F32), `n` the patch count, `tile_size` the
///   tile edge [`TILE`].
/// - `CPRM`: JSON `{"codec": NAME, "stats": {..}}`, NAME as
///   [`CodecKind::name`] writes it (read back with [`CodecKind::parse`]);
///   the encode statistics are informative (without the encode time, so
///   that the bytes are deterministic).
/// - `SCAL`: [`Encoded::scale`].
/// - `DENS`: [`Encoded::dense`], the stored tiles.
/// - `TIDX`: a 20-byte header (`channels u32`, `image_size u32`,
///   `tiles_per_side u32`, `log_range f32`, stored tiles `m u32`), then
///   `row_start` (`tiles_per_side + 1` × u32), `offsets` (m × u32) and
///   `cols` (m × u16).
/// - `SPRS`: a 24-byte header (`precision u32`: 0 none, 1 f32, 2 f16,
///   3 RGB9E5;
///   `col_bytes u32`: 2 or 4; positions `m u32`; the f16 scales 3 × f32),
///   then, when `m > 0` or precision is not 0, `row_ptr` (n + 1 × u32),
///   `cols` (m × u16 or u32) and the values (m × channels, f32, or f16 bit
///   patterns of value × scale; or m × u32 RGB9E5 words of value × scale).
///
/// [`Encoded::from_blob`] checks every length against the bytes present
/// before reading, then runs [`Encoded::check`] and rejects non-finite or
/// negative values, so a corrupt section is an error, never a panic or a
/// NaN at run time.
pub mod layout {
    /// Bytes of the `TIDX` header.
    pub const TILE_INDEX_HEADER: usize = 20;
    /// Bytes of the `SPRS` header.
    pub const SPARSE_HEADER: usize = 24;
}

impl DenseFormat {
    /// The format's code in the bake file's codec descriptor.
    pub fn code(self) -> u32 {
        match self {
            DenseFormat::Bc1 => 1,
            DenseFormat::Bc4 => 2,
            DenseFormat::Bc6h => 3,
            DenseFormat::F16 => 4,
            DenseFormat::F32 => 5,
        }
    }

    /// The format with code `c`.
    pub fn from_code(c: u32) -> Option<DenseFormat> {
        Some(match c {
            1 => DenseFormat::Bc1,
            2 => DenseFormat::Bc4,
            3 => DenseFormat::Bc6h,
            4 => DenseFormat::F16,
            5 => DenseFormat::F32,
            _ => return None,
        })
    }

    /// The dense format [`encode`] uses for `kind` with `channels` stored
    /// channels.
    fn of(kind: CodecKind, channels: usize) -> DenseFormat {
        match kind {
            CodecKind::Bc1Log { .. } if channels == 1 => DenseFormat::Bc4,
            CodecKind::Bc1Log { .. } => DenseFormat::Bc1,
            CodecKind::Bc4Log { .. } => DenseFormat::Bc4,
            CodecKind::Bc6h => DenseFormat::Bc6h,
            CodecKind::F16 => DenseFormat::F16,
            CodecKind::F32 => DenseFormat::F32,
        }
    }
}

/// A little-endian reader over one section that reports, instead of
/// panicking, when the bytes run out.
struct Cursor<'a> {
    bytes: &'a [u8],
    at: usize,
    section: &'static str,
}

impl<'a> Cursor<'a> {
    fn new(bytes: &'a [u8], section: &'static str) -> Cursor<'a> {
        Cursor {
            bytes,
            at: 0,
            section,
        }
    }

    fn err(&self, m: String) -> BakeError {
        BakeError::Stage {
            stage: STAGE,
            message: format!("codec section {}: {m}", self.section),
        }
    }

    /// The next `count` items of `size` bytes, after checking they exist.
    fn take(&mut self, count: usize, size: usize, what: &str) -> Result<&'a [u8], BakeError> {
        let len = count
            .checked_mul(size)
            .filter(|&l| l <= self.bytes.len() - self.at)
            .ok_or_else(|| {
                self.err(format!(
                    "{what}: {count} × {size} bytes needed at byte {}, {} left",
                    self.at,
                    self.bytes.len() - self.at
                ))
            })?;
        let s = &self.bytes[self.at..self.at + len];
        self.at += len;
        Ok(s)
    }

    fn u32(&mut self, what: &str) -> Result<u32, BakeError> {
        Ok(u32::from_le_bytes(
            self.take(1, 4, what)?.try_into().unwrap(),
        ))
    }

    fn u32s(&mut self, count: usize, what: &str) -> Result<Vec<u32>, BakeError> {
        Ok(self
            .take(count, 4, what)?
            .chunks_exact(4)
            .map(|c| u32::from_le_bytes(c.try_into().unwrap()))
            .collect())
    }

    fn u16s(&mut self, count: usize, what: &str) -> Result<Vec<u16>, BakeError> {
        Ok(self
            .take(count, 2, what)?
            .chunks_exact(2)
            .map(|c| u16::from_le_bytes(c.try_into().unwrap()))
            .collect())
    }

    fn finish(&self) -> Result<(), BakeError> {
        if self.at == self.bytes.len() {
            Ok(())
        } else {
            Err(self.err(format!(
                "{} trailing bytes after byte {}",
                self.bytes.len() - self.at,
                self.at
            )))
        }
    }
}

fn put_u32s(out: &mut Vec<u8>, v: impl IntoIterator<Item = u32>) {
    for x in v {
        out.extend_from_slice(&x.to_le_bytes());
    }
}

/// The codec parameters stored in `CPRM`.
#[derive(Serialize, serde::Deserialize)]
struct Params {
    codec: String,
    #[serde(default)]
    stats: EncodeStats,
}

impl Encoded {
    /// The bake file's codec sections for this matrix ([`layout`]).
    pub fn to_blob(&self) -> crate::bakefile::CodecBlob {
        let ix = &self.index;
        let mut tile_index = Vec::with_capacity(
            layout::TILE_INDEX_HEADER + ix.row_start.len() * 4 + ix.cols.len() * 6,
        );
        put_u32s(
            &mut tile_index,
            [
                self.channels as u32,
                self.image_size as u32,
                ix.tiles_per_side as u32,
                self.log_range.to_bits(),
                ix.cols.len() as u32,
            ],
        );
        put_u32s(&mut tile_index, ix.row_start.iter().copied());
        put_u32s(&mut tile_index, ix.offsets.iter().copied());
        for c in &ix.cols {
            tile_index.extend_from_slice(&c.to_le_bytes());
        }

        let sp = &self.sparse;
        let present = !sp.row_ptr.is_empty();
        let precision = match (present, sp.precision) {
            (false, _) => 0,
            (true, SparseValues::F32) => 1,
            (true, SparseValues::F16) => 2,
            (true, SparseValues::Rgb9e5) => 3,
        };
        let col_bytes: u32 = if self.n <= 1 << 16 { 2 } else { 4 };
        let mut sparse = Vec::with_capacity(layout::SPARSE_HEADER + self.bytes_sparse());
        put_u32s(&mut sparse, [precision, col_bytes, sp.cols.len() as u32]);
        put_u32s(&mut sparse, sp.scale.iter().map(|s| s.to_bits()));
        if present {
            put_u32s(&mut sparse, sp.row_ptr.iter().copied());
            for &c in &sp.cols {
                if col_bytes == 2 {
                    sparse.extend_from_slice(&(c as u16).to_le_bytes());
                } else {
                    sparse.extend_from_slice(&c.to_le_bytes());
                }
            }
            let ch = self.channels;
            match sp.precision {
                SparseValues::F32 => put_u32s(&mut sparse, sp.values.iter().map(|v| v.to_bits())),
                SparseValues::F16 => {
                    for (k, &v) in sp.values.iter().enumerate() {
                        let h = f16::from_f32(v * sp.scale[k % ch]);
                        sparse.extend_from_slice(&h.to_bits().to_le_bytes());
                    }
                }
                SparseValues::Rgb9e5 => put_u32s(
                    &mut sparse,
                    sp.values
                        .chunks_exact(3)
                        .map(|v| rgb9e5::pack(std::array::from_fn(|c| v[c] * sp.scale[c]))),
                ),
            }
        }
        // The encode time is left out: the same matrix must give the same
        // bytes (bake files are deterministic).
        let params = Params {
            codec: self.kind.name(),
            stats: EncodeStats {
                seconds: 0.0,
                ..self.stats.clone()
            },
        };
        crate::bakefile::CodecBlob {
            kind: self.format.code(),
            n: self.n as u32,
            tile_size: ix.tile as u32,
            params_json: serde_json::to_string(&params).expect("codec parameters serialize"),
            scales: self.scale,
            dense: self.dense.clone(),
            tile_index,
            sparse,
        }
    }

    /// Reads a matrix back from the bake file's codec sections, validating
    /// every field ([`layout`]); `to_blob` then `from_blob` gives back an
    /// equal matrix.
    pub fn from_blob(blob: &crate::bakefile::CodecBlob) -> Result<Encoded, BakeError> {
        let bad = |section: &str, m: String| BakeError::Stage {
            stage: STAGE,
            message: format!("codec section {section}: {m}"),
        };
        let params: Params = serde_json::from_str(&blob.params_json)
            .map_err(|e| bad("CPRM", format!("codec parameters: {e}")))?;
        let kind =
            CodecKind::parse(&params.codec).map_err(|e| bad("CPRM", format!("codec name: {e}")))?;
        let format = DenseFormat::from_code(blob.kind)
            .ok_or_else(|| bad("CDSC", format!("unknown dense format code {}", blob.kind)))?;
        let n = blob.n as usize;

        let mut c = Cursor::new(&blob.tile_index, "TIDX");
        let channels = c.u32("channels")? as usize;
        let image_size = c.u32("image size")? as usize;
        let tiles_per_side = c.u32("tiles per side")? as usize;
        let log_range = f32::from_bits(c.u32("log range")?);
        let stored = c.u32("stored tiles")? as usize;
        if !matches!(channels, 1 | 3) || format != DenseFormat::of(kind, channels) {
            return Err(bad(
                "TIDX",
                format!("{channels} channels in format {format:?} do not match codec {kind}"),
            ));
        }
        let row_start = c.u32s(tiles_per_side.saturating_add(1), "tile row starts")?;
        let offsets = c.u32s(stored, "tile offsets")?;
        let cols = c.u16s(stored, "tile columns")?;
        c.finish()?;

        let mut c = Cursor::new(&blob.sparse, "SPRS");
        let precision = c.u32("precision")?;
        let col_bytes = c.u32("column bytes")?;
        let entries = c.u32("positions")? as usize;
        let scale_bits = c.u32s(3, "f16 scales")?;
        let sparse_scale: [f32; 3] = std::array::from_fn(|k| f32::from_bits(scale_bits[k]));
        let mut sparse = Sparse {
            precision: match precision {
                2 => SparseValues::F16,
                3 => SparseValues::Rgb9e5,
                _ => SparseValues::F32,
            },
            scale: sparse_scale,
            ..Sparse::default()
        };
        let expect_cols = if n <= 1 << 16 { 2 } else { 4 };
        if precision > 3
            || col_bytes != expect_cols
            || (precision == 0 && entries != 0)
            || (precision == 3 && channels != 3)
        {
            return Err(bad(
                "SPRS",
                format!(
                    "precision {precision}, {col_bytes}-byte columns and {entries} positions \
                     are not a valid header for n = {n}"
                ),
            ));
        }
        if precision != 0 {
            sparse.row_ptr = c.u32s(n.saturating_add(1), "row pointers")?;
            sparse.cols = if col_bytes == 2 {
                c.u16s(entries, "columns")?
                    .into_iter()
                    .map(u32::from)
                    .collect()
            } else {
                c.u32s(entries, "columns")?
            };
            let count = entries.saturating_mul(channels);
            if precision != 1 && sparse_scale.iter().any(|s| !(s.is_finite() && *s > 0.0)) {
                return Err(bad("SPRS", format!("value scales {sparse_scale:?}")));
            }
            sparse.values = match precision {
                1 => c
                    .u32s(count, "values")?
                    .into_iter()
                    .map(f32::from_bits)
                    .collect(),
                2 => c
                    .u16s(count, "values")?
                    .into_iter()
                    .enumerate()
                    .map(|(k, b)| f16::from_bits(b).to_f32() / sparse_scale[k % channels])
                    .collect(),
                _ => c
                    .u32s(entries, "values")?
                    .into_iter()
                    .flat_map(|p| {
                        let v = rgb9e5::unpack(p);
                        [0, 1, 2].map(|k| v[k] / sparse_scale[k])
                    })
                    .collect(),
            };
            if let Some(v) = sparse
                .values
                .iter()
                .find(|v| !(v.is_finite() && **v >= 0.0))
            {
                return Err(bad("SPRS", format!("value {v} is not finite and ≥ 0")));
            }
        }
        c.finish()?;

        let e = Encoded {
            kind,
            n,
            channels,
            format,
            image_size,
            scale: blob.scales,
            log_range,
            index: TileIndex {
                tile: blob.tile_size as usize,
                tiles_per_side,
                row_start,
                cols,
                offsets,
            },
            dense: blob.dense.clone(),
            sparse,
            stats: params.stats,
        };
        e.check()?;
        if e.scale.iter().any(|s| *s < 0.0) || e.log_range < 0.0 {
            return Err(bad(
                "SCAL",
                format!(
                    "negative scale or log range ({:?}, {})",
                    e.scale, e.log_range
                ),
            ));
        }
        // Plain formats are values already: a non-finite or negative one is
        // corruption the checksums did not catch (a hostile file).
        let bad_value = match format {
            DenseFormat::F32 => e
                .dense
                .chunks_exact(4)
                .map(|b| f32::from_le_bytes(b.try_into().unwrap()))
                .find(|v| !(v.is_finite() && *v >= 0.0)),
            DenseFormat::F16 => e
                .dense
                .chunks_exact(2)
                .map(|b| f16::from_le_bytes(b.try_into().unwrap()).to_f32())
                .find(|v| !(v.is_finite() && *v >= 0.0)),
            _ => None,
        };
        if let Some(v) = bad_value {
            return Err(bad("DENS", format!("value {v} is not finite and ≥ 0")));
        }
        Ok(e)
    }
}

/// Seeded synthetic transfer matrices with the structure of real ones, for
/// tests, benchmarks and the compression report when no scene is at hand.
///
/// A closed room of `m × m` patches per wall (a voxelized box: wall patches
/// in the boundary voxel layer, facing inwards) with a Cornell-box palette,
/// optionally a box of `b³` voxels in the middle with outward patches, in
/// the voxelizer's order (voxel key, then direction). Form factors are the
/// point-to-area approximation `F_ij = max(0, cos θ_i) max(0, cos θ_j)
/// A_j / (π r²)` without visibility, each row scaled down to a sum of 1 when
/// above (the approximation overestimates between adjacent patches), so
/// `F` keeps the invariants that matter here (non-negative, exact zeros
/// between coplanar patches, row sums ≤ 1). `T_∞ = F (I − diag(ρ) F)^{-1}`
/// per channel, solved in f64 with faer.
pub mod synthetic {
    use crate::core::patch::Direction;
    use crate::core::patch::Patch;
    use faer::linalg::solvers::Solve as _;
    use rayon::prelude::*;

    /// The seeded generator of the synthetic inputs.
    pub use crate::core::math::SplitMix64 as Rng;

    /// The Cornell box's wall albedos: the −x wall red, the +x wall green,
    /// the rest white.
    fn wall_albedo(facing: Direction) -> [f64; 3] {
        match facing {
            Direction::PosX => [0.63, 0.065, 0.05],
            Direction::NegX => [0.14, 0.45, 0.09],
            _ => [0.7, 0.7, 0.7],
        }
    }

    /// The room's patches (module doc); the room is the unit cube, `m`
    /// voxels per edge; `b` (0: none) the edge of the central box in voxels.
    pub fn room(m: usize, b: usize) -> Vec<Patch> {
        assert!(m >= 2 && b + 2 <= m);
        let size = 1.0 / m as f64;
        let mut out: Vec<(u64, Patch)> = Vec::new();
        let lo_box = (m - b) / 2;
        for z in 0..m {
            for y in 0..m {
                for x in 0..m {
                    let v = [x, y, z];
                    for d in Direction::ALL {
                        let a = d.axis();
                        // Walls: the boundary layer, facing inwards.
                        let wall = (v[a] == 0 && d.sign() > 0) || (v[a] == m - 1 && d.sign() < 0);
                        // The box: its boundary voxels, facing outwards.
                        let inside = |k: usize| k >= lo_box && k < lo_box + b;
                        let in_box = b > 0 && v.iter().all(|&k| inside(k));
                        let box_face = in_box
                            && ((d.sign() > 0 && v[a] == lo_box + b - 1)
                                || (d.sign() < 0 && v[a] == lo_box));
                        if !(wall || box_face) {
                            continue;
                        }
                        let normal = d.vector();
                        // The face of the voxel the patch looks out of.
                        let mut centre = [0.0; 3];
                        for k in 0..3 {
                            centre[k] = (v[k] as f64 + 0.5) * size;
                        }
                        centre[a] += 0.5 * size * d.sign() as f64;
                        let albedo = if wall {
                            wall_albedo(d)
                        } else {
                            [0.7, 0.7, 0.7]
                        };
                        let key = (x + m * (y + m * z)) as u64 * 6 + d as u64;
                        out.push((
                            key,
                            Patch {
                                centre,
                                normal,
                                area: size * size,
                                albedo,
                                emission: [0.0; 3],
                                voxel: [x as u32, y as u32, z as u32],
                                direction: d,
                            },
                        ));
                    }
                }
            }
        }
        out.sort_by_key(|p| p.0);
        out.into_iter().map(|p| p.1).collect()
    }

    /// Point-to-area form factors without visibility, rows scaled to sum
    /// ≤ 1 (module doc). Row-major n × n.
    pub fn form_factors(patches: &[Patch]) -> Vec<f32> {
        let n = patches.len();
        let mut f = vec![0.0f32; n * n];
        f.par_chunks_mut(n).enumerate().for_each(|(i, row)| {
            let p = &patches[i];
            let mut vals = vec![0.0f64; n];
            for (j, q) in patches.iter().enumerate() {
                if i == j {
                    continue;
                }
                let d: [f64; 3] = std::array::from_fn(|k| q.centre[k] - p.centre[k]);
                let r2: f64 = d.iter().map(|x| x * x).sum();
                if r2 <= 0.0 {
                    continue;
                }
                let r = r2.sqrt();
                let ci: f64 = (0..3).map(|k| p.normal[k] * d[k]).sum::<f64>() / r;
                let cj: f64 = -(0..3).map(|k| q.normal[k] * d[k]).sum::<f64>() / r;
                if ci > 0.0 && cj > 0.0 {
                    vals[j] = ci * cj * q.area / (std::f64::consts::PI * r2);
                }
            }
            let sum: f64 = vals.iter().sum();
            let s = if sum > 1.0 { 1.0 / sum } else { 1.0 };
            for (o, v) in row.iter_mut().zip(vals) {
                *o = (v * s) as f32;
            }
        });
        f
    }

    /// `T_∞ = F (I − diag(ρ) F)^{-1}` in f64 (faer LU), rounded to f32.
    pub fn transfer(f: &[f32], n: usize, rho: &[f64]) -> Vec<f32> {
        let fm = faer::Mat::<f64>::from_fn(n, n, |i, j| f[i * n + j] as f64);
        let m = faer::Mat::<f64>::from_fn(n, n, |i, j| {
            f64::from(i == j) - rho[i] * f[i * n + j] as f64
        });
        let t = m.partial_piv_lu().rsolve(fm.as_ref());
        (0..n * n).map(|k| t[(k / n, k % n)] as f32).collect()
    }

    /// The three channels of `T_∞` for the patches' albedos.
    pub fn transfer_rgb(patches: &[Patch], f: &[f32]) -> [Vec<f32>; 3] {
        let n = patches.len();
        std::array::from_fn(|c| {
            let rho: Vec<f64> = patches.iter().map(|p| p.albedo[c]).collect();
            transfer(f, n, &rho)
        })
    }

    /// `count` seeded point lights inside the room (positions uniform in
    /// the middle 80 % of the unit cube, RGB intensities in [0.5, 1]), as
    /// `B0 = ρ ∘ D` with `D_j = I max(0, cos θ_j) / r²` (no shadows).
    pub fn point_lights(patches: &[Patch], count: usize, seed: u64) -> Vec<[Vec<f32>; 3]> {
        let mut rng = Rng(seed);
        (0..count)
            .map(|_| {
                let pos: [f64; 3] = std::array::from_fn(|_| 0.1 + 0.8 * rng.uniform());
                let power: [f64; 3] = std::array::from_fn(|_| 0.5 + 0.5 * rng.uniform());
                std::array::from_fn(|c| {
                    patches
                        .iter()
                        .map(|p| {
                            let d: [f64; 3] = std::array::from_fn(|k| pos[k] - p.centre[k]);
                            let r2: f64 = d.iter().map(|x| x * x).sum::<f64>().max(1e-6);
                            let cos = (0..3).map(|k| p.normal[k] * d[k]).sum::<f64>() / r2.sqrt();
                            (p.albedo[c] * power[c] * cos.max(0.0) / r2) as f32
                        })
                        .collect()
                })
            })
            .collect()
    }
}
