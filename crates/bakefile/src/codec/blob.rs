//! The codec's sections of a bake file: serialisation of an [`Encoded`]
//! matrix into them and validation when reading them back, so that a
//! corrupt section is an error, never a panic or a NaN at run time.

use super::rgb9e5;
use super::{
    CodecDataError, CodecKind, DenseFormat, EncodeStats, Encoded, Sparse, SparseValues, TileIndex,
    MAX_TILE,
};
use crate::section_error::SectionError;
use crate::CodecBlob;
use half::f16;
use serde::Serialize;

/// The codec sections of a bake file (`bakefile::CodecBlob`): how an
/// [`Encoded`] matrix is laid out in `CDSC`, `CPRM`, `SCAL`, `DENS`, `TIDX`
/// and `SPRS`. All integers are little-endian.
///
/// - `CDSC`: `kind` is the dense format ([`DenseFormat::code`]: 1 BC1,
///   2 BC4, 3 BC6H, 4 F16, 5 F32), `n` the patch count, `tile_size` the
///   tile edge `TILE`.
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

    fn err(&self, m: String) -> CodecDataError {
        CodecDataError {
            section: self.section,
            detail: m,
        }
    }

    /// The next `count` items of `size` bytes, after checking they exist.
    fn take(&mut self, count: usize, size: usize, what: &str) -> Result<&'a [u8], CodecDataError> {
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

    fn u32(&mut self, what: &str) -> Result<u32, CodecDataError> {
        Ok(u32::from_le_bytes(
            self.take(1, 4, what)?.try_into().unwrap(),
        ))
    }

    fn u32s(&mut self, count: usize, what: &str) -> Result<Vec<u32>, CodecDataError> {
        Ok(self
            .take(count, 4, what)?
            .chunks_exact(4)
            .map(|c| u32::from_le_bytes(c.try_into().unwrap()))
            .collect())
    }

    fn u16s(&mut self, count: usize, what: &str) -> Result<Vec<u16>, CodecDataError> {
        Ok(self
            .take(count, 2, what)?
            .chunks_exact(2)
            .map(|c| u16::from_le_bytes(c.try_into().unwrap()))
            .collect())
    }

    fn finish(&self) -> Result<(), CodecDataError> {
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
    /// Checks the internal consistency of an encoding (for one read back
    /// from a file): sizes, index ranges and offsets, so that decoding
    /// cannot index out of bounds. A message names the first problem.
    pub fn check(&self) -> Result<(), CodecDataError> {
        let bad = |m: String| {
            Err(CodecDataError {
                section: "TIDX",
                detail: format!("invalid encoded matrix: {m}"),
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
        check_col_scale(&self.col_scale, n).map_err(|e| CodecDataError {
            section: "CCOL",
            detail: e.to_string(),
        })?;
        Ok(())
    }

    /// The bake file's codec sections for this matrix ([`layout`]).
    pub fn to_blob(&self) -> CodecBlob {
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
        CodecBlob {
            kind: self.format.code(),
            n: self.n as u32,
            tile_size: ix.tile as u32,
            params_json: serde_json::to_string(&params).expect("codec parameters serialize"),
            scales: self.scale,
            dense: self.dense.clone(),
            tile_index,
            sparse,
            col_scale: self.col_scale.clone(),
        }
    }

    /// Reads a matrix back from the bake file's codec sections, validating
    /// every field ([`layout`]); `to_blob` then `from_blob` gives back an
    /// equal matrix.
    pub fn from_blob(blob: &CodecBlob) -> Result<Encoded, CodecDataError> {
        let bad = |section: &'static str, m: String| CodecDataError { section, detail: m };
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
            col_scale: blob.col_scale.clone(),
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

/// The column scales' rule ([`Encoded::col_scale`]): none, or one finite
/// value > 0 per patch; the message names the first fault. Shared by the
/// matrix's check and the bake file's validation before writing.
pub fn check_col_scale(s: &[f32], n: usize) -> Result<(), SectionError> {
    if !s.is_empty() && s.len() != n {
        return Err(SectionError::Length {
            found: 4 * s.len() as u64,
            expected: 4 * n as u64,
            layout: format!("{} column scales for {n} patches", s.len()),
        });
    }
    match s
        .iter()
        .enumerate()
        .find(|(_, v)| !(v.is_finite() && **v > 0.0))
    {
        Some((j, v)) => Err(SectionError::Invalid(format!(
            "column {j}'s scale is {v}: must be finite and > 0"
        ))),
        None => Ok(()),
    }
}
