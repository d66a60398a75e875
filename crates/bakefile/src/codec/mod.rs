//! The compressed transfer matrix (docs/design.md section 2, "Compression"; bake
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
//! **Column scales** (optional, [`Encoded::col_scale`], `n` × f32 > 0): the
//! two parts then hold `T' = T diag(1/s)` and every decoder multiplies
//! `s ∘ B0` (the decoded matrix is `T' diag(s)`). A column of `T` scales
//! with the area of the patch it comes from, so patches of very different
//! areas next to each other make one 4 × 4 block span more magnitudes than
//! its log range holds; the bake also tries each setting on the matrix with
//! every column divided by its patch's area relative to the largest
//! (`bake::column_scales`) and keeps the cheaper. On Sponza at 3,946
//! patches (areas from 1.4e-5 to 9.7 m²) that halves BC1's error of `H` at
//! a given top fraction (2 %: 6.3 → 2.9 %), and the default error bound is
//! met with half the sparse entries; at 12,872 it does not help
//! (`docs/runtime.md`).
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
//!      dense entries (`auto_log_range`): every byte level is then as
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
//! for `x > 0` and to 0 for `x = 0`. [`decode`] and [`Encoded::gather`]
//! decode BC1 with `bcdec_rs`, which rounds the interpolated colours to the
//! nearest of 256 levels, and map the byte through a 256-entry table; BC4,
//! BC6H and the plain formats decode at float precision. Every run-time
//! decoder — the CPU gather and the GL gather's shader — computes the same
//! bytes and levels with the same integer arithmetic and tables, so all of
//! them see the same f32 matrix. Texture units would not: they interpolate
//! BC1's palette at their own precision (Mesa's llvmpipe truncates, up to
//! one level low, a factor `e^{L/255}`: 1.6 % at the room's automatic
//! L ≈ 4, 10 % at L = 25; NVIDIA's H200 decoded entries ~3 levels from
//! `bcdec_rs`), which is why the GL gather does not use them. Black texels
//! (BC1 index 3 in 3-colour mode, BC4 index 6 in 6-level mode) are exactly
//! 0 on every decoder.
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
//! `choose` encodes every candidate, measures the relative RMS error of
//! `H = T̃ · B0` over sample lights through the f64 gather (`h_error`: no
//! decoded n × n copy), and keeps the cheapest whose error is within the
//! bound. `measure` adds the per-entry and Frobenius errors of a decoded
//! matrix; `bench::compression::report_rows` and `report_table` tabulate errors, bytes and
//! times for every reordering and codec. `synthetic` builds test
//! matrices with the structure of real ones.

pub mod blob;
pub mod decode;
pub mod rgb9e5;

use serde::Serialize;

/// Edge of a tile of the dense part, in texels (a multiple of 4).
pub const TILE: usize = 32;

/// The largest tile edge a valid encoding may declare (the reader's bound;
/// the encoder uses [`TILE`]); positions inside a tile then fit a byte
/// each, which the run time's sparse layout relies on.
pub const MAX_TILE: usize = 256;

/// The thesis's log range `L`: bytes span `[e^{−L}, 1]` of the maximum.
pub const DEFAULT_LOG_RANGE: f32 = 25.0;

/// `log_range` value asking for the range to be chosen from the data
/// (`auto_log_range`).
pub const LOG_RANGE_AUTO: f32 = 0.0;

/// The share of the smallest nonzero dense entries an automatic log range
/// may flush to zero.
pub const AUTO_FLUSH_QUANTILE: f64 = 1e-3;

/// The thesis's top fraction stored exactly.
pub const DEFAULT_TOP_FRACTION: f64 = 0.04;

/// An invalid codec setting: a name that does not parse, or a parameter out
/// of its range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CodecSettingError {
    #[error(
        "invalid codec {input:?}: {why} (expected f32, f16, bc6h, bc1 or bc4, e.g. \
         bc1:top=0.04,L=25,sparse=f32)"
    )]
    Parse { input: String, why: String },
    #[error("top fraction must lie in [0, 1], got {0}")]
    TopFraction(f64),
    #[error("log range L must be a positive number or 0 (automatic), got {0}")]
    LogRange(f32),
    #[error("a top fraction applies to the bc1 and bc4 codecs, not {0}")]
    NoSparsePart(String),
}

/// Encoded data that is not a valid encoding: a corrupt or hostile codec
/// section of a bake file, named by its tag.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("codec section {section}: {detail}")]
pub struct CodecDataError {
    pub section: &'static str,
    pub detail: String,
}

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
    /// docs/design.md's setting: BC1 + log + the top 4 % kept in the sparse
    /// part, with the log range chosen from the data (`auto_log_range`)
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
    pub fn parse(s: &str) -> Result<CodecKind, CodecSettingError> {
        let t = s.trim().to_ascii_lowercase();
        let bad = |why: String| CodecSettingError::Parse {
            input: s.to_string(),
            why,
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
    pub fn validate(&self) -> Result<(), CodecSettingError> {
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
                return Err(CodecSettingError::TopFraction(top_fraction));
            }
            if !(log_range.is_finite() && log_range >= 0.0) {
                return Err(CodecSettingError::LogRange(log_range));
            }
        }
        Ok(())
    }

    /// The same setting with another top fraction: an error for the
    /// formats without a sparse part.
    pub fn with_top_fraction(self, f: f64) -> Result<CodecKind, CodecSettingError> {
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
            other => return Err(CodecSettingError::NoSparsePart(other.name())),
        };
        kind.validate()?;
        Ok(kind)
    }

    /// The (top fraction, log range, sparse precision) of the log formats.
    pub fn log_params(&self) -> Option<(f64, f32, SparseValues)> {
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
    /// Wall-clock seconds of `encode`.
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
    /// Per column `j`, the factor `s_j > 0` the stored matrix's column was
    /// divided by: the matrix is `T̃ = T' diag(s)`, with `T'` what the
    /// dense and sparse parts hold, so every product is `T' (s ∘ B0)`.
    /// Empty: no column scaling (`s = 1`). The bake may divide each column
    /// by its patch's area relative to the largest (module doc, "Column
    /// scales").
    #[serde(skip)]
    pub col_scale: Vec<f32>,
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
        self.index.row_start.len() * 4
            + self.index.cols.len() * (2 + 4)
            + 16
            + 4 * self.col_scale.len()
    }

    pub fn bytes_total(&self) -> usize {
        self.bytes_dense() + self.bytes_sparse() + self.bytes_index()
    }

    /// The share of the dense part's tiles that are zero in every channel
    /// and therefore neither stored nor read.
    pub fn zero_tile_fraction(&self) -> f64 {
        let tiles = self.index.tiles_per_side * self.index.tiles_per_side;
        if tiles == 0 {
            0.0
        } else {
            1.0 - self.index.cols.len() as f64 / tiles as f64
        }
    }

    /// All bytes per matrix entry, the three channels together:
    /// `bytes_total / n²` (module doc).
    pub fn bytes_per_entry(&self) -> f64 {
        if self.n == 0 {
            return 0.0;
        }
        self.bytes_total() as f64 / (self.n * self.n) as f64
    }
}

impl DenseFormat {
    /// The dense format the encoder (`bake::encode`) uses for `kind` with `channels` stored
    /// channels.
    pub fn of(kind: CodecKind, channels: usize) -> DenseFormat {
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

/// The channels of `t` that carry distinct data: one when all three are
/// equal (a grey scene: stored, gathered and shaded once), else three.
pub fn distinct_channels(t: [&[f32]; 3]) -> Vec<&[f32]> {
    let same = |a: &[f32], b: &[f32]| std::ptr::eq(a, b) || a == b;
    if same(t[0], t[1]) && same(t[1], t[2]) {
        vec![t[0]]
    } else {
        t.to_vec()
    }
}

/// `1 / max` of each channel (0 for an all-zero channel): the per-channel
/// normalisation under which every channel counts alike (the sparse
/// ranking, the reordering's row features).
pub fn inverse_maxima(channels: &[&[f32]]) -> Vec<f32> {
    use rayon::prelude::*;
    channels
        .iter()
        .map(|ch| {
            let m = ch.par_iter().cloned().reduce(|| 0.0f32, f32::max);
            if m > 0.0 {
                1.0 / m
            } else {
                0.0
            }
        })
        .collect()
}

/// The three channels of `b0` times the column scales `s`
/// ([`Encoded::col_scale`]): what a column-scaled matrix multiplies (one
/// f32 product per value; every decoder and the bake's error measure round
/// it alike).
pub fn scaled_input(b0: [&[f32]; 3], s: &[f32]) -> [Vec<f32>; 3] {
    std::array::from_fn(|c| b0[c].iter().zip(s).map(|(x, s)| x * s).collect())
}
