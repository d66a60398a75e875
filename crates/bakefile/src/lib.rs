//! The bake file (`.rad`): everything the run time needs from one bake, in
//! one versioned, checksummed container (docs/design.md section 1, bake step 8,
//! and section 4: "a truncated, corrupt or newer-version file is a clear
//! error, never a panic or garbage").
//!
//! The container follows the pattern of binary formats such as PNG chunks
//! and meshoptimizer's codecs: a magic number, a format version checked
//! before anything else, an explicit little-endian layout and a table of
//! tagged sections, each with its own checksum.
//!
//! # Layout (format v2, all integers little-endian)
//!
//! | offset | size     | field                                                   |
//! |-------:|---------:|---------------------------------------------------------|
//! |      0 |        8 | magic `b"RADBAKE\0"`                                     |
//! |      8 |        4 | format version `u32` (= [`FORMAT_VERSION`])             |
//! |     12 |        4 | flags `u32`, 0 (none are defined in v2)                 |
//! |     16 |        8 | file length in bytes `u64`                              |
//! |     24 |        4 | section count `u32` (at most `MAX_SECTIONS`)          |
//! |     28 |        4 | header checksum `u32` (see below)                       |
//! |     32 | 24 × cnt | section table: per section `tag [u8; 4]`, `crc u32`, `offset u64`, `length u64` |
//! |    ... |      ... | section bodies, each starting at a multiple of 8, gaps zero-filled |
//!
//! **Checksums.** Every checksum is CRC-32 (IEEE 802.3, reflected polynomial
//! `0xEDB88320`, initial value and final XOR `0xFFFFFFFF`: the CRC of zlib,
//! PNG and gzip; check value `crc32(b"123456789") = 0xCBF43926`). A CRC-32
//! detects every error burst up to 32 bits long, so every single changed
//! byte, and any other corruption except with probability 2^-32. Each
//! section carries the CRC of its bytes; the header checksum is the CRC of
//! bytes `0..28` followed by the whole section table. As the table holds
//! every section's CRC, the header checksum covers the whole file
//! transitively (a Merkle-style whole-file checksum) while every byte is
//! hashed exactly once; the bytes outside sections are alignment padding
//! that the reader requires to be zero, so no byte of a file escapes
//! validation.
//!
//! **Sections** (all required in v2; [`tag`] has the constants):
//!
//! | tag    | content                                                                   |
//! |--------|---------------------------------------------------------------------------|
//! | `OPTS` | the options record [`records::OptionsRecord`], JSON text (UTF-8)          |
//! | `SRCH` | the source scene's content hash, [`SceneHash`]: 4 × `u64`                 |
//! | `PTCH` | the patches, `n` records of 13 × `f32` ([`PatchRecord`], 52 bytes)        |
//! | `PERM` | the reordering permutation, `n` × `u32`                                   |
//! | `CDSC` | codec descriptor: `kind u32`, `n u32`, `tile_size u32`, `flags u32`      |
//! | `CPRM` | codec parameters, JSON text                                               |
//! | `SCAL` | the codec's channel scales, 3 × `f32`                                     |
//! | `DENS` | the dense codec data (opaque to this module, e.g. BC1 blocks)             |
//! | `TIDX` | the tile index (opaque)                                                   |
//! | `SPRS` | the sparse correction (opaque)                                            |
//! | `CCOL` | with flag bit 0 of `CDSC`: the matrix's column scales, `n` × `f32` > 0     |
//! | `MMAP` | the mesh-to-patch map, per vertex 4 × (`u32` patch, `f32` weight)         |
//! | `SMAP` | the per-pixel surface map ([`surface`] gives the layout)                  |
//! | `PSMP` | the patches' sample points ([`surface`])                                  |
//! | `NEAR` | optional: the near-field correction ([`near_field`] gives the layout)     |
//! | `SKYV` | optional: the patches' sky visibility ([`sky`] gives the layout)           |
//! | `PROB` | optional: irradiance probes and their transfers ([`probes`] gives the layout) |
//! | `INFO` | the bake report record [`records::BakeInfo`], JSON text                   |
//!
//! Sections are found through the table, never by position; the writer
//! emits them in the order above. A section with an unknown tag is checked
//! against its CRC and otherwise ignored, so later versions can add
//! optional sections without breaking readers of this version; any change
//! such a reader would misread bumps [`FORMAT_VERSION`]. Version history:
//! v1 stored a serialisation of the command line in `OPTS`; v2 stores the
//! versioned records of [`records`]. A file of an older version is an
//! error that asks for a new bake (a bake is cheap to redo, and a reader
//! that guesses at an old layout risks garbage).
//!
//! **Validation.** [`parse`] checks, in this order: the magic, the version
//! (a newer one is reported as such before anything else is read, because
//! a newer layout may differ from here on), the header length, the section
//! count, the header checksum, the declared file length against the real
//! one (truncation), the table (alignment, bounds, duplicated tags,
//! overlaps, non-zero or oversized gaps), every section's checksum, the
//! required sections, and finally every field ([`validate`]): record sizes,
//! finite values, unit normals, albedo in [0, 1), the permutation, the
//! codec's patch count, the mesh map's indices and weights, UTF-8 and JSON.
//! No allocation is sized by a length field before that length has been
//! checked against the bytes actually present, and nothing panics on any
//! input (`tests/bakefile/` truncates a file at every byte, flips random
//! bytes and feeds arbitrary bytes; `fuzz/` holds a cargo-fuzz target).
//!
//! **Determinism.** The same [`BakeFile`] always encodes to the same bytes:
//! fixed section order, zero padding, no timestamps (a bake report that
//! wants one puts it in `INFO` itself).
//!
//! **Atomic writes.** [`write()`] writes a temporary file in the target's
//! directory, flushes it to disk (`fsync`), then renames it over the target:
//! a reader sees the old file or the new one, never a partial file, and a
//! failed write leaves the old file untouched and removes the temporary.

// NaN-aware tests: `!(x > 0.0)` is true for NaN, which is the point.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod baked;
pub mod codec;
pub mod container;
pub mod hash;
pub mod near_field;
pub mod probes;
pub mod records;
pub mod section_error;
pub mod sky;
pub mod surface;

pub use container::{
    crc32, is_bake_file, sections, tag_name, BakeFileError, Crc32, Section, FORMAT_VERSION,
    IN_MEMORY, MAGIC,
};
pub use hash::SceneHash;
pub use section_error::SectionError;

use container::{encode_sections, le_u32, write_atomic};
use near_field::NearField;
use probes::Probes;
use serde::Serialize;
use sky::SkyVisibility;
use std::path::Path;
use surface::{PatchSamples, SurfaceMap};

/// Bytes per patch record in `PTCH`: 13 `f32`.
pub const PATCH_RECORD_LEN: usize = 52;

/// Bytes per vertex in `MMAP`: 4 × (`u32`, `f32`).
pub const MAP_ENTRY_LEN: usize = 32;

/// Bytes of the codec descriptor `CDSC`.
pub const CODEC_DESCRIPTOR_LEN: usize = 16;

/// Bit 0 of the codec descriptor's flags (its fourth field, 0 in files
/// written before column scales existed, and refused when not 0 by the
/// readers of those files): the matrix's column scales follow in `CCOL`.
pub const CODEC_FLAG_COLUMN_SCALES: u32 = 1;

/// Tolerance on the sum of a mesh-map row's weights. A row is normalised in
/// f64 and stored as four f32 values; each rounding moves the sum by at most
/// 2^-24 ≈ 6e-8 (weights are ≤ 1), so a correct row is within 2.4e-7 of 1.
/// 1e-5 leaves room for writers that normalise in f32, and still rejects any
/// row whose weights were damaged.
pub const WEIGHT_SUM_TOLERANCE: f64 = 1e-5;

/// Tolerance on the length of a stored patch normal: a unit f64 normal
/// rounded to f32 has length within ~1e-7 of 1; 1e-3 rejects anything that
/// is not a unit vector while accepting normals normalised in f32.
pub const NORMAL_LENGTH_TOLERANCE: f64 = 1e-3;

/// Section tags.
pub mod tag {
    /// Bake options, JSON.
    pub const OPTIONS: [u8; 4] = *b"OPTS";
    /// Source scene hash.
    pub const SCENE_HASH: [u8; 4] = *b"SRCH";
    /// Patch records.
    pub const PATCHES: [u8; 4] = *b"PTCH";
    /// Reordering permutation.
    pub const PERMUTATION: [u8; 4] = *b"PERM";
    /// Codec descriptor.
    pub const CODEC: [u8; 4] = *b"CDSC";
    /// Codec parameters, JSON.
    pub const CODEC_PARAMS: [u8; 4] = *b"CPRM";
    /// Channel scales.
    pub const SCALES: [u8; 4] = *b"SCAL";
    /// Dense codec data.
    pub const DENSE: [u8; 4] = *b"DENS";
    /// Tile index.
    pub const TILE_INDEX: [u8; 4] = *b"TIDX";
    /// Sparse correction.
    pub const SPARSE: [u8; 4] = *b"SPRS";
    /// The matrix's column scales (present when bit 0 of the codec
    /// descriptor's flags is set: [`super::CODEC_FLAG_COLUMN_SCALES`]).
    pub const COLUMN_SCALES: [u8; 4] = *b"CCOL";
    /// Mesh-to-patch map.
    pub const MESH_MAP: [u8; 4] = *b"MMAP";
    /// The per-pixel surface map.
    pub const SURFACE_MAP: [u8; 4] = *b"SMAP";
    /// The patches' sample points.
    pub const SAMPLES: [u8; 4] = *b"PSMP";
    /// The near-field correction (optional: a file without it loads with
    /// none).
    pub const NEAR_FIELD: [u8; 4] = *b"NEAR";
    /// The patches' sky visibility (optional: a file without it loads with
    /// none).
    pub const SKY: [u8; 4] = *b"SKYV";
    /// Irradiance probes (optional: a file without them loads with none).
    pub const PROBES: [u8; 4] = *b"PROB";
    /// Bake report, JSON.
    pub const INFO: [u8; 4] = *b"INFO";

    /// Every section of this format version, in the order the writer emits them.
    pub const REQUIRED: [[u8; 4]; 14] = [
        OPTIONS,
        SCENE_HASH,
        PATCHES,
        PERMUTATION,
        CODEC,
        CODEC_PARAMS,
        SCALES,
        DENSE,
        TILE_INDEX,
        SPARSE,
        MESH_MAP,
        SURFACE_MAP,
        SAMPLES,
        INFO,
    ];
}

/// What a section holds, for error messages.
pub fn section_what(t: [u8; 4]) -> &'static str {
    match t {
        tag::OPTIONS => "bake options",
        tag::SCENE_HASH => "scene hash",
        tag::PATCHES => "patches",
        tag::PERMUTATION => "permutation",
        tag::CODEC => "codec descriptor",
        tag::CODEC_PARAMS => "codec parameters",
        tag::SCALES => "channel scales",
        tag::DENSE => "dense codec data",
        tag::TILE_INDEX => "tile index",
        tag::SPARSE => "sparse correction",
        tag::COLUMN_SCALES => "column scales",
        tag::MESH_MAP => "mesh-to-patch map",
        tag::SURFACE_MAP => "surface map",
        tag::SAMPLES => "patch sample points",
        tag::NEAR_FIELD => "near-field correction",
        tag::SKY => "sky visibility",
        tag::PROBES => "irradiance probes",
        tag::INFO => "bake report",
        _ => "unknown section",
    }
}

/// One patch as stored: the f32 rounding of [`radiosity_core::patch::Patch`]'s
/// centre `c_i`, unit normal `N_i`, area `A_i`, albedo `ρ_i` and emission
/// `E_i` (docs/design.md section 2), in matrix order.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct PatchRecord {
    pub centre: [f32; 3],
    pub normal: [f32; 3],
    pub area: f32,
    pub albedo: [f32; 3],
    pub emission: [f32; 3],
}

impl From<&radiosity_core::patch::Patch> for PatchRecord {
    fn from(p: &radiosity_core::patch::Patch) -> PatchRecord {
        PatchRecord {
            centre: p.centre.map(|x| x as f32),
            normal: p.normal.map(|x| x as f32),
            area: p.area as f32,
            albedo: p.albedo.map(|x| x as f32),
            emission: p.emission.map(|x| x as f32),
        }
    }
}

impl PatchRecord {
    fn values(&self) -> [f32; 13] {
        let mut v = [0.0; 13];
        v[0..3].copy_from_slice(&self.centre);
        v[3..6].copy_from_slice(&self.normal);
        v[6] = self.area;
        v[7..10].copy_from_slice(&self.albedo);
        v[10..13].copy_from_slice(&self.emission);
        v
    }

    fn from_values(v: [f32; 13]) -> PatchRecord {
        PatchRecord {
            centre: [v[0], v[1], v[2]],
            normal: [v[3], v[4], v[5]],
            area: v[6],
            albedo: [v[7], v[8], v[9]],
            emission: [v[10], v[11], v[12]],
        }
    }
}

/// The compressed transfer matrix as the codec produced it. The blobs are
/// opaque here: the codec module defines and validates their contents;
/// this module checks that `n` equals the number of patches and that the
/// scales are finite and non-negative.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CodecBlob {
    /// Which codec wrote the data (values defined by the codec module).
    pub kind: u32,
    /// Matrix size: the number of patches.
    pub n: u32,
    /// Tile edge in matrix entries (codec-defined; 0 when unused).
    pub tile_size: u32,
    /// Codec parameters, JSON text (e.g. sparse fraction, log range `L`).
    pub params_json: String,
    /// Per colour channel scale of the dense part (the thesis's per-channel
    /// maximum), R, G, B.
    pub scales: [f32; 3],
    /// The dense part (e.g. BC1 blocks).
    pub dense: Vec<u8>,
    /// The tile index.
    pub tile_index: Vec<u8>,
    /// The exact sparse correction.
    pub sparse: Vec<u8>,
    /// The matrix's column scales (`CCOL`), empty when it has none.
    pub col_scale: Vec<f32>,
}

/// Everything one bake leaves for the run time.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BakeFile {
    /// The bake options, JSON text.
    pub options_json: String,
    /// The source scene's content hash.
    pub scene_hash: SceneHash,
    /// The patches, in matrix order (patch `i` is row and column `i` of `T`
    /// before reordering).
    pub patches: Vec<PatchRecord>,
    /// The reordering (docs/design.md bake step 5): row and column `r` of the
    /// codec's matrix hold patch `permutation[r]`. A permutation of `0..n`.
    pub permutation: Vec<u32>,
    /// The compressed transfer matrix.
    pub codec: CodecBlob,
    /// Per mesh vertex, up to four (patch, weight) pairs in matrix order
    /// (`radiosity_bake::mesh_map`): weights ≥ 0 summing to 1, unused slots
    /// `(0, 0.0)`; a vertex no patch could light has four unused slots.
    pub mesh_map: Vec<[(u32, f32); 4]>,
    /// The per-pixel surface map ([`surface`]), patch indices in file order.
    pub surface_map: SurfaceMap,
    /// The patches' sample points ([`surface`]), in file order.
    pub samples: PatchSamples,
    /// The near-field correction ([`near_field`]), in file order; written
    /// only when not empty.
    pub near_field: NearField,
    /// The patches' sky visibility ([`sky`]), in file order; written only
    /// when not empty.
    pub sky: SkyVisibility,
    /// The irradiance probes ([`probes`]), their patches in file order;
    /// written only when there are some.
    pub probes: Probes,
    /// Free-form bake report, JSON text.
    pub info_json: String,
}

// ---------------------------------------------------------------------------
// Validation

fn invalid(file: &str, t: [u8; 4], detail: impl Into<SectionError>) -> BakeFileError {
    BakeFileError::Invalid {
        file: file.to_string(),
        tag: tag_name(t),
        what: section_what(t),
        detail: detail.into(),
    }
}

/// Checks every field of `bf` (the module doc lists the rules); `file`
/// names it in messages. [`parse`] runs this on what it decoded and
/// [`encode`] on what it is given, so the writer never produces a file the
/// reader rejects.
pub fn validate(bf: &BakeFile, file: &str) -> Result<(), BakeFileError> {
    for (t, text) in [
        (tag::OPTIONS, &bf.options_json),
        (tag::CODEC_PARAMS, &bf.codec.params_json),
        (tag::INFO, &bf.info_json),
    ] {
        // serde_json bounds nesting at 128 levels, so hostile input cannot
        // exhaust the stack.
        if let Err(e) = serde_json::from_str::<serde_json::Value>(text) {
            return Err(invalid(file, t, format!("not valid JSON: {e}")));
        }
    }

    let n = bf.patches.len();
    if n > u32::MAX as usize {
        return Err(invalid(
            file,
            tag::PATCHES,
            format!("{n} patches exceed the u32 index range"),
        ));
    }
    for (i, p) in bf.patches.iter().enumerate() {
        let bad = |field: &str, why: &str| {
            invalid(
                file,
                tag::PATCHES,
                format!("patch {i}: {field} {why} (record {p:?})"),
            )
        };
        if let Some(k) = p.values().iter().position(|v| !v.is_finite()) {
            let field = ["centre", "normal", "area", "albedo", "emission"]
                [[0, 0, 0, 1, 1, 1, 2, 3, 3, 3, 4, 4, 4][k]];
            return Err(bad(field, "is not finite"));
        }
        let len = p
            .normal
            .iter()
            .map(|&x| x as f64 * x as f64)
            .sum::<f64>()
            .sqrt();
        if (len - 1.0).abs() > NORMAL_LENGTH_TOLERANCE {
            return Err(bad(
                "normal",
                &format!("has length {len}, not 1 (±{NORMAL_LENGTH_TOLERANCE})"),
            ));
        }
        if !(p.area > 0.0) {
            return Err(bad("area", "is not positive"));
        }
        if p.albedo.iter().any(|&a| !(0.0..1.0).contains(&a)) {
            return Err(bad("albedo", "is outside [0, 1)"));
        }
        if p.emission.iter().any(|&e| e < 0.0) {
            return Err(bad("emission", "is negative"));
        }
    }

    if bf.permutation.len() != n {
        return Err(invalid(
            file,
            tag::PERMUTATION,
            format!(
                "{} entries for {n} patches: not a permutation of 0..{n}",
                bf.permutation.len()
            ),
        ));
    }
    let mut seen = vec![false; n];
    for (r, &p) in bf.permutation.iter().enumerate() {
        let Some(s) = seen.get_mut(p as usize) else {
            return Err(invalid(
                file,
                tag::PERMUTATION,
                format!("entry {r} is {p}, outside 0..{n}: not a permutation of 0..{n}"),
            ));
        };
        if *s {
            return Err(invalid(
                file,
                tag::PERMUTATION,
                format!(
                    "patch {p} appears twice (again at entry {r}): not a permutation of 0..{n}"
                ),
            ));
        }
        *s = true;
    }

    if bf.codec.n as usize != n {
        return Err(invalid(
            file,
            tag::CODEC,
            format!("field n is {} but the file holds {n} patches", bf.codec.n),
        ));
    }
    if let Some(c) = bf
        .codec
        .scales
        .iter()
        .position(|s| !(s.is_finite() && *s >= 0.0))
    {
        return Err(invalid(
            file,
            tag::SCALES,
            format!(
                "channel {} scale is {}: must be finite and ≥ 0",
                ["R", "G", "B"][c],
                bf.codec.scales[c]
            ),
        ));
    }

    codec::blob::check_col_scale(&bf.codec.col_scale, n)
        .map_err(|d| invalid(file, tag::COLUMN_SCALES, d))?;

    bf.surface_map
        .check(n)
        .map_err(|d| invalid(file, tag::SURFACE_MAP, d))?;
    bf.samples
        .check(n, NORMAL_LENGTH_TOLERANCE)
        .map_err(|d| invalid(file, tag::SAMPLES, d))?;
    bf.near_field
        .check(n)
        .map_err(|d| invalid(file, tag::NEAR_FIELD, d))?;
    bf.sky.check(n).map_err(|d| invalid(file, tag::SKY, d))?;
    bf.probes
        .check(n)
        .map_err(|d| invalid(file, tag::PROBES, d))?;
    for (v, row) in bf.mesh_map.iter().enumerate() {
        let mut sum = 0.0f64;
        for (s, &(p, w)) in row.iter().enumerate() {
            let at = format!("vertex {v}, slot {s}");
            if !w.is_finite() || w < 0.0 {
                return Err(invalid(
                    file,
                    tag::MESH_MAP,
                    format!("{at}: weight {w} is not a finite number ≥ 0"),
                ));
            }
            if w == 0.0 && p != 0 {
                return Err(invalid(
                    file,
                    tag::MESH_MAP,
                    format!("{at}: an unused slot (weight 0) must have patch 0, found patch {p}"),
                ));
            }
            if w > 0.0 && p as usize >= n {
                return Err(invalid(
                    file,
                    tag::MESH_MAP,
                    format!("{at}: patch index {p} is out of range (the file holds {n} patches)"),
                ));
            }
            sum += w as f64;
        }
        if sum != 0.0 && (sum - 1.0).abs() > WEIGHT_SUM_TOLERANCE {
            return Err(invalid(
                file,
                tag::MESH_MAP,
                format!(
                    "vertex {v}: weights sum to {sum}, not 1 (±{WEIGHT_SUM_TOLERANCE}) or 0 \
                     (weights {:?})",
                    row.map(|(_, w)| w)
                ),
            ));
        }
    }
    Ok(())
}

fn f32s_to_bytes(values: impl IntoIterator<Item = f32>, out: &mut Vec<u8>) {
    for v in values {
        out.extend_from_slice(&v.to_le_bytes());
    }
}

/// Encodes `bf` to the bytes of a `.rad` file after [`validate`] (errors
/// name `(in-memory bake file)`). Deterministic: the same value always
/// gives the same bytes.
pub fn encode(bf: &BakeFile) -> Result<Vec<u8>, BakeFileError> {
    encode_named(bf, IN_MEMORY)
}

fn encode_named(bf: &BakeFile, file: &str) -> Result<Vec<u8>, BakeFileError> {
    validate(bf, file).map_err(|e| BakeFileError::Refused(Box::new(e)))?;
    let mut patches = Vec::with_capacity(bf.patches.len() * PATCH_RECORD_LEN);
    for p in &bf.patches {
        f32s_to_bytes(p.values(), &mut patches);
    }
    let mut perm = Vec::with_capacity(bf.permutation.len() * 4);
    for p in &bf.permutation {
        perm.extend_from_slice(&p.to_le_bytes());
    }
    let mut codec = Vec::with_capacity(CODEC_DESCRIPTOR_LEN);
    let flags = if bf.codec.col_scale.is_empty() {
        0
    } else {
        CODEC_FLAG_COLUMN_SCALES
    };
    for v in [bf.codec.kind, bf.codec.n, bf.codec.tile_size, flags] {
        codec.extend_from_slice(&v.to_le_bytes());
    }
    let mut col_scales = Vec::with_capacity(4 * bf.codec.col_scale.len());
    f32s_to_bytes(bf.codec.col_scale.iter().copied(), &mut col_scales);
    let mut scales = Vec::with_capacity(12);
    f32s_to_bytes(bf.codec.scales, &mut scales);
    let mut map = Vec::with_capacity(bf.mesh_map.len() * MAP_ENTRY_LEN);
    for row in &bf.mesh_map {
        for &(p, w) in row {
            map.extend_from_slice(&p.to_le_bytes());
            map.extend_from_slice(&w.to_le_bytes());
        }
    }
    let hash = bf.scene_hash.to_bytes();
    let smap = bf.surface_map.to_bytes();
    let psmp = bf.samples.to_bytes();
    let near = bf.near_field.to_bytes();
    let sky = bf.sky.to_bytes();
    let probes = bf.probes.to_bytes();
    let mut sections: Vec<([u8; 4], &[u8])> = vec![
        (tag::OPTIONS, bf.options_json.as_bytes()),
        (tag::SCENE_HASH, &hash),
        (tag::PATCHES, &patches),
        (tag::PERMUTATION, &perm),
        (tag::CODEC, &codec),
        (tag::CODEC_PARAMS, bf.codec.params_json.as_bytes()),
        (tag::SCALES, &scales),
        (tag::DENSE, &bf.codec.dense),
        (tag::TILE_INDEX, &bf.codec.tile_index),
        (tag::SPARSE, &bf.codec.sparse),
    ];
    if flags & CODEC_FLAG_COLUMN_SCALES != 0 {
        sections.push((tag::COLUMN_SCALES, &col_scales));
    }
    sections.extend_from_slice(&[
        (tag::MESH_MAP, &map[..]),
        (tag::SURFACE_MAP, &smap),
        (tag::SAMPLES, &psmp),
    ]);
    if !bf.near_field.is_empty() {
        sections.push((tag::NEAR_FIELD, &near));
    }
    if !bf.sky.is_empty() {
        sections.push((tag::SKY, &sky));
    }
    if !bf.probes.is_empty() {
        sections.push((tag::PROBES, &probes));
    }
    sections.push((tag::INFO, bf.info_json.as_bytes()));
    debug_assert!(sections
        .iter()
        .map(|s| s.0)
        .filter(|t| ![tag::NEAR_FIELD, tag::SKY, tag::PROBES, tag::COLUMN_SCALES].contains(t))
        .eq(tag::REQUIRED));
    Ok(encode_sections(&sections))
}

/// Writes `bf` to `path` atomically ([`container::write_atomic`]): readers
/// see the old file or the complete new one. An invalid `bf` is refused
/// before anything is written.
pub fn write(path: &Path, bf: &BakeFile) -> Result<(), BakeFileError> {
    write_impl(path, bf, None)
}

/// Test support: [`write`], but the temporary file's write fails with an
/// injected I/O error after `fail_after` bytes, as a full disk would.
#[doc(hidden)]
pub fn write_failing_after(
    path: &Path,
    bf: &BakeFile,
    fail_after: usize,
) -> Result<(), BakeFileError> {
    write_impl(path, bf, Some(fail_after))
}

fn write_impl(path: &Path, bf: &BakeFile, fail_after: Option<usize>) -> Result<(), BakeFileError> {
    let bytes = encode_named(bf, &path.display().to_string())?;
    write_atomic(path, &bytes, fail_after).map_err(|source| BakeFileError::Write {
        path: path.to_path_buf(),
        source,
    })
}

// ---------------------------------------------------------------------------
// Reading

/// Reads and validates a `.rad` file.
pub fn read(path: &Path) -> Result<BakeFile, BakeFileError> {
    let bytes = std::fs::read(path).map_err(|source| BakeFileError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    parse_named(&bytes, &path.display().to_string())
}

/// Parses and validates the bytes of a `.rad` file (errors name
/// `(in-memory bake file)`). Never panics.
pub fn parse(bytes: &[u8]) -> Result<BakeFile, BakeFileError> {
    parse_named(bytes, IN_MEMORY)
}

/// Parses and validates `bytes`, naming them `file` in messages.
pub fn parse_named(bytes: &[u8], file: &str) -> Result<BakeFile, BakeFileError> {
    let secs = sections(bytes, file)?;
    let get = |t: [u8; 4]| -> Result<&[u8], BakeFileError> {
        secs.iter()
            .find(|s| s.tag == t)
            .map(|s| s.bytes)
            .ok_or_else(|| BakeFileError::MissingSection {
                file: file.to_string(),
                tag: tag_name(t),
                what: section_what(t),
            })
    };
    // Report every missing section by the first one in writer order.
    for t in tag::REQUIRED {
        get(t)?;
    }
    let text = |t: [u8; 4]| -> Result<String, BakeFileError> {
        String::from_utf8(get(t)?.to_vec())
            .map_err(|e| invalid(file, t, format!("not valid UTF-8 text: {e}")))
    };
    let exact = |t: [u8; 4], want: usize| -> Result<&[u8], BakeFileError> {
        let b = get(t)?;
        if b.len() != want {
            return Err(invalid(
                file,
                t,
                format!("{} bytes, expected exactly {want}", b.len()),
            ));
        }
        Ok(b)
    };
    let multiple = |t: [u8; 4], unit: usize, what: &str| -> Result<&[u8], BakeFileError> {
        let b = get(t)?;
        if b.len() % unit != 0 {
            return Err(invalid(
                file,
                t,
                format!(
                    "{} bytes is not a whole number of {unit}-byte {what}",
                    b.len()
                ),
            ));
        }
        Ok(b)
    };

    let options_json = text(tag::OPTIONS)?;
    let hash: &[u8; 32] = exact(tag::SCENE_HASH, 32)?
        .try_into()
        .expect("length checked");
    let scene_hash = SceneHash::from_bytes(hash);

    let f32_at = |b: &[u8], at: usize| f32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]]);
    let patches: Vec<PatchRecord> = multiple(tag::PATCHES, PATCH_RECORD_LEN, "patch records")?
        .chunks_exact(PATCH_RECORD_LEN)
        .map(|r| PatchRecord::from_values(std::array::from_fn(|k| f32_at(r, 4 * k))))
        .collect();
    let n = patches.len();
    let permutation: Vec<u32> = multiple(tag::PERMUTATION, 4, "u32 entries")?
        .chunks_exact(4)
        .map(|c| le_u32(c, 0))
        .collect();
    let desc = exact(tag::CODEC, CODEC_DESCRIPTOR_LEN)?;
    let flags = le_u32(desc, 12);
    if flags & !CODEC_FLAG_COLUMN_SCALES != 0 {
        return Err(invalid(
            file,
            tag::CODEC,
            format!("flags are {flags:#x}: this build knows only bit 0 (column scales)"),
        ));
    }
    let col_scale_section = secs.iter().find(|s| s.tag == tag::COLUMN_SCALES);
    let col_scale: Vec<f32> = match (flags & CODEC_FLAG_COLUMN_SCALES != 0, col_scale_section) {
        (true, Some(_)) => multiple(tag::COLUMN_SCALES, 4, "f32 column scales")?
            .chunks_exact(4)
            .map(|c| f32_at(c, 0))
            .collect(),
        (false, None) => Vec::new(),
        (true, None) => {
            return Err(invalid(
                file,
                tag::CODEC,
                "flag bit 0 says the column scales follow, but there is no CCOL section",
            ))
        }
        (false, Some(_)) => {
            return Err(invalid(
                file,
                tag::COLUMN_SCALES,
                "column scales present but the codec descriptor's flag bit 0 is not set",
            ))
        }
    };
    let scales_b = exact(tag::SCALES, 12)?;
    let codec = CodecBlob {
        kind: le_u32(desc, 0),
        n: le_u32(desc, 4),
        tile_size: le_u32(desc, 8),
        params_json: text(tag::CODEC_PARAMS)?,
        scales: std::array::from_fn(|c| f32_at(scales_b, 4 * c)),
        dense: get(tag::DENSE)?.to_vec(),
        tile_index: get(tag::TILE_INDEX)?.to_vec(),
        sparse: get(tag::SPARSE)?.to_vec(),
        col_scale,
    };
    let mesh_map: Vec<[(u32, f32); 4]> = multiple(tag::MESH_MAP, MAP_ENTRY_LEN, "vertex entries")?
        .chunks_exact(MAP_ENTRY_LEN)
        .map(|r| std::array::from_fn(|s| (le_u32(r, 8 * s), f32_at(r, 8 * s + 4))))
        .collect();
    let info_json = text(tag::INFO)?;
    let bf = BakeFile {
        options_json,
        scene_hash,
        patches,
        permutation,
        codec,
        surface_map: SurfaceMap::from_bytes(get(tag::SURFACE_MAP)?, n)
            .map_err(|d| invalid(file, tag::SURFACE_MAP, d))?,
        samples: PatchSamples::from_bytes(get(tag::SAMPLES)?, n, NORMAL_LENGTH_TOLERANCE)
            .map_err(|d| invalid(file, tag::SAMPLES, d))?,
        near_field: match secs.iter().find(|s| s.tag == tag::NEAR_FIELD) {
            Some(s) => {
                NearField::from_bytes(s.bytes, n).map_err(|d| invalid(file, tag::NEAR_FIELD, d))?
            }
            None => NearField::none(),
        },
        sky: match secs.iter().find(|s| s.tag == tag::SKY) {
            Some(s) => {
                SkyVisibility::from_bytes(s.bytes, n).map_err(|d| invalid(file, tag::SKY, d))?
            }
            None => SkyVisibility::none(),
        },
        probes: match secs.iter().find(|s| s.tag == tag::PROBES) {
            Some(s) => Probes::from_bytes(s.bytes, n).map_err(|d| invalid(file, tag::PROBES, d))?,
            None => Probes::none(),
        },
        mesh_map,
        info_json,
    };
    validate(&bf, file)?;
    Ok(bf)
}
