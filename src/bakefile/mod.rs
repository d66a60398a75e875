//! The bake file (`.rad`): everything the run time needs from one bake, in
//! one versioned, checksummed container (DESIGN.md section 1, bake step 8,
//! and section 4: "a truncated, corrupt or newer-version file is a clear
//! error, never a panic or garbage").
//!
//! The container follows the pattern of binary formats such as PNG chunks
//! and meshoptimizer's codecs: a magic number, a format version checked
//! before anything else, an explicit little-endian layout and a table of
//! tagged sections, each with its own checksum.
//!
//! # Layout (format v1, all integers little-endian)
//!
//! | offset | size     | field                                                   |
//! |-------:|---------:|---------------------------------------------------------|
//! |      0 |        8 | magic `b"RADBAKE\0"`                                     |
//! |      8 |        4 | format version `u32` (= [`FORMAT_VERSION`])             |
//! |     12 |        4 | flags `u32`, 0 (none are defined in v1)                 |
//! |     16 |        8 | file length in bytes `u64`                              |
//! |     24 |        4 | section count `u32` (at most [`MAX_SECTIONS`])          |
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
//! **Sections** (all required in v1; [`tag`] has the constants):
//!
//! | tag    | content                                                                   |
//! |--------|---------------------------------------------------------------------------|
//! | `OPTS` | the bake options, JSON text (UTF-8)                                       |
//! | `SRCH` | the source scene's content hash, [`SceneHash`]: 4 × `u64`                 |
//! | `PTCH` | the patches, `n` records of 13 × `f32` ([`PatchRecord`], 52 bytes)        |
//! | `PERM` | the reordering permutation, `n` × `u32`                                   |
//! | `CDSC` | codec descriptor: `kind u32`, `n u32`, `tile_size u32`, reserved `u32` = 0 |
//! | `CPRM` | codec parameters, JSON text                                               |
//! | `SCAL` | the codec's channel scales, 3 × `f32`                                     |
//! | `DENS` | the dense codec data (opaque to this module, e.g. BC1 blocks)             |
//! | `TIDX` | the tile index (opaque)                                                   |
//! | `SPRS` | the sparse correction (opaque)                                            |
//! | `MMAP` | the mesh-to-patch map, per vertex 4 × (`u32` patch, `f32` weight)         |
//! | `INFO` | free-form bake report, JSON text                                          |
//!
//! Sections are found through the table, never by position; the writer
//! emits them in the order above. A section with an unknown tag is checked
//! against its CRC and otherwise ignored, so later versions can add
//! optional sections without breaking v1 readers; any change a v1 reader
//! would misread bumps [`FORMAT_VERSION`].
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
//! input (`tests/bakefile.rs` truncates a file at every byte, flips random
//! bytes and feeds arbitrary bytes; `fuzz/` holds a cargo-fuzz target).
//!
//! **Determinism.** The same [`BakeFile`] always encodes to the same bytes:
//! fixed section order, zero padding, no timestamps (a bake report that
//! wants one puts it in `INFO` itself).
//!
//! **Atomic writes.** [`write`] writes a temporary file in the target's
//! directory, flushes it to disk (`fsync`), then renames it over the target:
//! a reader sees the old file or the new one, never a partial file, and a
//! failed write leaves the old file untouched and removes the temporary.

pub mod codec;

use crate::core::scene::Scene;
use serde::Serialize;
use std::fs::File;
use std::io::{self, Read, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// The first 8 bytes of every bake file.
pub const MAGIC: [u8; 8] = *b"RADBAKE\0";

/// The format version this build writes and reads.
pub const FORMAT_VERSION: u32 = 1;

/// Length of the fixed header before the section table.
pub const HEADER_LEN: usize = 32;

/// Length of one section-table entry.
pub const ENTRY_LEN: usize = 24;

/// Sections start at multiples of this, so that a memory-mapped reader can
/// view `f32`/`u32`/`u64` arrays in place.
pub const ALIGN: usize = 8;

/// Most sections a file may have: v1 writes 12; the bound keeps a corrupt
/// count from making the reader walk a huge table.
pub const MAX_SECTIONS: u32 = 256;

/// Bytes per patch record in `PTCH`: 13 `f32`.
pub const PATCH_RECORD_LEN: usize = 52;

/// Bytes per vertex in `MMAP`: 4 × (`u32`, `f32`).
pub const MAP_ENTRY_LEN: usize = 32;

/// Bytes of the codec descriptor `CDSC`.
pub const CODEC_DESCRIPTOR_LEN: usize = 16;

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
    /// Mesh-to-patch map.
    pub const MESH_MAP: [u8; 4] = *b"MMAP";
    /// Bake report, JSON.
    pub const INFO: [u8; 4] = *b"INFO";

    /// Every section of format v1, in the order the writer emits them.
    pub const V1: [[u8; 4]; 12] = [
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
        INFO,
    ];
}

/// What a section holds, for error messages.
fn section_what(t: [u8; 4]) -> &'static str {
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
        tag::MESH_MAP => "mesh-to-patch map",
        tag::INFO => "bake report",
        _ => "unknown section",
    }
}

/// A tag as text: its four characters when they are printable ASCII, else
/// its value in hex.
pub fn tag_name(t: [u8; 4]) -> String {
    if t.iter().all(|b| b.is_ascii_graphic() || *b == b' ') {
        t.iter().map(|&b| b as char).collect()
    } else {
        format!("0x{:08x}", u32::from_le_bytes(t))
    }
}

/// Errors of this module. Every message names the file (or
/// `(in-memory bake file)` for [`parse`]) and the section or field at fault.
#[derive(Debug, thiserror::Error)]
pub enum BakeFileError {
    #[error("cannot read bake file {path}: {source}")]
    Read {
        path: PathBuf,
        #[source]
        source: io::Error,
    },
    #[error("cannot write bake file {path}: {source}")]
    Write {
        path: PathBuf,
        #[source]
        source: io::Error,
    },
    #[error("cannot hash scene file {path}: {source}")]
    SceneHash {
        path: PathBuf,
        #[source]
        source: io::Error,
    },
    #[error("refusing to write an invalid bake file: {0}")]
    Refused(Box<BakeFileError>),
    #[error("{file}: not a radiosity bake file (it starts with {found}, expected \"RADBAKE\\0\")")]
    NotABakeFile { file: String, found: String },
    #[error(
        "{file}: written by a newer radiosity (format v{found}); this build reads v{supported}"
    )]
    NewerVersion {
        file: String,
        found: u32,
        supported: u32,
    },
    #[error("{file}: format version {found} does not exist (this build reads v{supported})")]
    BadVersion {
        file: String,
        found: u32,
        supported: u32,
    },
    #[error("{file}: truncated: {detail}")]
    Truncated { file: String, detail: String },
    #[error("{file}: header: {detail}")]
    Header { file: String, detail: String },
    #[error(
        "{file}: header checksum mismatch (stored {stored:#010x}, computed {computed:#010x}): \
         the header or the section table is corrupt"
    )]
    HeaderChecksum {
        file: String,
        stored: u32,
        computed: u32,
    },
    #[error("{file}: section table: {detail}")]
    Table { file: String, detail: String },
    #[error(
        "{file}: section {tag} ({what}): checksum mismatch (stored {stored:#010x}, computed \
         {computed:#010x}): the section is corrupt"
    )]
    SectionChecksum {
        file: String,
        tag: String,
        what: &'static str,
        stored: u32,
        computed: u32,
    },
    #[error("{file}: missing required section {tag} ({what})")]
    MissingSection {
        file: String,
        tag: String,
        what: &'static str,
    },
    #[error("{file}: section {tag} ({what}): {detail}")]
    Invalid {
        file: String,
        tag: String,
        what: &'static str,
        detail: String,
    },
}

/// Whether `path` starts with the bake file magic (false when it cannot be
/// read: the caller's own open then reports why).
pub fn is_bake_file(path: &Path) -> bool {
    let mut head = [0u8; 8];
    File::open(path)
        .and_then(|mut f| f.read_exact(&mut head))
        .is_ok()
        && head == MAGIC
}

/// Name used in messages for bytes that did not come from a named file.
pub const IN_MEMORY: &str = "(in-memory bake file)";

// ---------------------------------------------------------------------------
// Checksums

/// CRC-32 lookup tables for slicing-by-8 (Kounavis and Berry, "A Systematic
/// Approach to Building High Performance Software-Based CRC Generators",
/// 2005): `T[0]` is the classic byte table, `T[s][i]` advances `T[s-1][i]`
/// by one more zero byte.
const CRC_TABLES: [[u32; 256]; 8] = {
    let mut t = [[0u32; 256]; 8];
    let mut i = 0;
    while i < 256 {
        let mut c = i as u32;
        let mut k = 0;
        while k < 8 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
            k += 1;
        }
        t[0][i] = c;
        i += 1;
    }
    let mut i = 0;
    while i < 256 {
        let mut s = 1;
        while s < 8 {
            t[s][i] = (t[s - 1][i] >> 8) ^ t[0][(t[s - 1][i] & 0xff) as usize];
            s += 1;
        }
        i += 1;
    }
    t
};

/// Streaming CRC-32 (IEEE; the module doc gives the parameters), eight
/// bytes per step.
#[derive(Clone, Copy, Debug)]
pub struct Crc32 {
    state: u32,
}

impl Default for Crc32 {
    fn default() -> Self {
        Self::new()
    }
}

impl Crc32 {
    /// A fresh checksum (of zero bytes).
    pub fn new() -> Crc32 {
        Crc32 { state: !0 }
    }

    /// Feeds `bytes`.
    pub fn update(&mut self, bytes: &[u8]) {
        let t = &CRC_TABLES;
        let mut c = self.state;
        let mut chunks = bytes.chunks_exact(8);
        for ch in &mut chunks {
            let lo = u32::from_le_bytes([ch[0], ch[1], ch[2], ch[3]]) ^ c;
            let hi = u32::from_le_bytes([ch[4], ch[5], ch[6], ch[7]]);
            c = t[7][(lo & 0xff) as usize]
                ^ t[6][((lo >> 8) & 0xff) as usize]
                ^ t[5][((lo >> 16) & 0xff) as usize]
                ^ t[4][(lo >> 24) as usize]
                ^ t[3][(hi & 0xff) as usize]
                ^ t[2][((hi >> 8) & 0xff) as usize]
                ^ t[1][((hi >> 16) & 0xff) as usize]
                ^ t[0][(hi >> 24) as usize];
        }
        for &b in chunks.remainder() {
            c = t[0][((c ^ b as u32) & 0xff) as usize] ^ (c >> 8);
        }
        self.state = c;
    }

    /// The checksum of everything fed so far.
    pub fn finish(&self) -> u32 {
        !self.state
    }
}

/// CRC-32 of `bytes`.
pub fn crc32(bytes: &[u8]) -> u32 {
    let mut c = Crc32::new();
    c.update(bytes);
    c.finish()
}

/// Streaming 64-bit FNV-1a (Fowler, Noll, Vo; offset basis
/// `0xcbf29ce484222325`, prime `0x100000001b3`), used for content hashes of
/// the scene files. Not cryptographic: it identifies an input, it does not
/// defend against a forger. Each step `h ← (h ⊕ b) · p` is a bijection of
/// `h` (the prime is odd), so two inputs of equal length that differ in one
/// byte always hash differently.
#[derive(Clone, Copy, Debug)]
pub struct Fnv1a64 {
    state: u64,
}

impl Default for Fnv1a64 {
    fn default() -> Self {
        Self::new()
    }
}

impl Fnv1a64 {
    /// A fresh hash (of zero bytes): the offset basis.
    pub fn new() -> Fnv1a64 {
        Fnv1a64 {
            state: 0xcbf2_9ce4_8422_2325,
        }
    }

    /// Feeds `bytes`.
    pub fn update(&mut self, bytes: &[u8]) {
        let mut h = self.state;
        for &b in bytes {
            h ^= b as u64;
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
        self.state = h;
    }

    /// The hash of everything fed so far.
    pub fn finish(&self) -> u64 {
        self.state
    }
}

// ---------------------------------------------------------------------------
// The content

/// Content hash of the scene a bake was made from, so a viewer can tell
/// that the scene changed since. Each part is a 64-bit FNV-1a ([`Fnv1a64`]),
/// computed streaming.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct SceneHash {
    /// The OBJ file's bytes.
    pub obj: u64,
    /// The OBJ file's length in bytes.
    pub obj_len: u64,
    /// Every material library named by an `mtllib` line, in the order of
    /// the lines: for each, the name as written, a byte saying whether the
    /// file could be read, its bytes and their count as a `u64`.
    pub mtl: u64,
    /// Every diffuse texture the scene loaded, in material order: its path
    /// (as the loader resolved it), its bytes and their count.
    pub textures: u64,
}

impl SceneHash {
    /// Hashes the files `scene` was loaded from: its OBJ, the MTL files the
    /// OBJ names (resolved next to it, as the loader does) and the loaded
    /// diffuse textures. A missing MTL file is hashed as missing (the loader
    /// accepts it with a warning); an unreadable OBJ or texture is an error.
    pub fn of_scene(scene: &Scene) -> Result<SceneHash, BakeFileError> {
        let obj_path = &scene.source;
        let err = |path: &Path| {
            let path = path.to_path_buf();
            move |source| BakeFileError::SceneHash { path, source }
        };
        let dir = obj_path.parent().unwrap_or_else(|| Path::new(""));
        let mut obj = Fnv1a64::new();
        let mut libraries: Vec<String> = Vec::new();
        let mut obj_len = 0u64;
        // Stream the OBJ once: hash every byte and collect `mtllib` names
        // line by line (the name is the rest of the line, trimmed, as tobj
        // reads it).
        let mut file = File::open(obj_path).map_err(err(obj_path))?;
        let mut buf = vec![0u8; 1 << 16];
        let mut line: Vec<u8> = Vec::new();
        loop {
            let k = file.read(&mut buf).map_err(err(obj_path))?;
            if k == 0 {
                break;
            }
            obj.update(&buf[..k]);
            obj_len += k as u64;
            for &b in &buf[..k] {
                if b == b'\n' {
                    collect_mtllib(&line, &mut libraries);
                    line.clear();
                } else if line.len() < 4096 {
                    line.push(b);
                }
            }
        }
        collect_mtllib(&line, &mut libraries);

        let mut mtl = Fnv1a64::new();
        for name in &libraries {
            mtl.update(name.as_bytes());
            match File::open(dir.join(name)) {
                Ok(f) if !dir.join(name).is_dir() => {
                    mtl.update(&[1]);
                    let n = hash_stream(f, &mut mtl).map_err(err(&dir.join(name)))?;
                    mtl.update(&n.to_le_bytes());
                }
                _ => mtl.update(&[0]),
            }
        }
        let mut textures = Fnv1a64::new();
        for m in &scene.materials {
            if let Some(t) = &m.diffuse_texture {
                textures.update(t.to_string_lossy().as_bytes());
                let f = File::open(t).map_err(err(t))?;
                let n = hash_stream(f, &mut textures).map_err(err(t))?;
                textures.update(&n.to_le_bytes());
            }
        }
        Ok(SceneHash {
            obj: obj.finish(),
            obj_len,
            mtl: mtl.finish(),
            textures: textures.finish(),
        })
    }

    /// The parts that differ from `other` (`"obj"`, `"mtl"`, `"textures"`),
    /// for a message such as "the scene's MTL changed since the bake".
    pub fn differences(&self, other: &SceneHash) -> Vec<&'static str> {
        let mut d = Vec::new();
        if self.obj != other.obj || self.obj_len != other.obj_len {
            d.push("obj");
        }
        if self.mtl != other.mtl {
            d.push("mtl");
        }
        if self.textures != other.textures {
            d.push("textures");
        }
        d
    }

    fn to_bytes(self) -> [u8; 32] {
        let mut b = [0u8; 32];
        for (i, v) in [self.obj, self.obj_len, self.mtl, self.textures]
            .iter()
            .enumerate()
        {
            b[8 * i..8 * i + 8].copy_from_slice(&v.to_le_bytes());
        }
        b
    }

    fn from_bytes(b: &[u8; 32]) -> SceneHash {
        let v = |i: usize| u64::from_le_bytes(b[8 * i..8 * i + 8].try_into().unwrap());
        SceneHash {
            obj: v(0),
            obj_len: v(1),
            mtl: v(2),
            textures: v(3),
        }
    }
}

/// Adds the library named by `line` if it is an `mtllib` line.
fn collect_mtllib(line: &[u8], out: &mut Vec<String>) {
    let text = String::from_utf8_lossy(line);
    let text = text.trim_end_matches('\r');
    if text.split_whitespace().next() == Some("mtllib") {
        let name = text.split_once(' ').unwrap_or_default().1.trim();
        out.push(name.to_string());
    }
}

/// Feeds a whole stream to `h`, returning its length.
fn hash_stream(mut r: impl Read, h: &mut Fnv1a64) -> io::Result<u64> {
    let mut buf = vec![0u8; 1 << 16];
    let mut n = 0u64;
    loop {
        let k = r.read(&mut buf)?;
        if k == 0 {
            return Ok(n);
        }
        h.update(&buf[..k]);
        n += k as u64;
    }
}

/// One patch as stored: the f32 rounding of [`crate::core::patch::Patch`]'s
/// centre `c_i`, unit normal `N_i`, area `A_i`, albedo `ρ_i` and emission
/// `E_i` (DESIGN.md section 2), in matrix order.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct PatchRecord {
    pub centre: [f32; 3],
    pub normal: [f32; 3],
    pub area: f32,
    pub albedo: [f32; 3],
    pub emission: [f32; 3],
}

impl From<&crate::core::patch::Patch> for PatchRecord {
    fn from(p: &crate::core::patch::Patch) -> PatchRecord {
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
    /// The reordering (DESIGN.md bake step 5): row and column `r` of the
    /// codec's matrix hold patch `permutation[r]`. A permutation of `0..n`.
    pub permutation: Vec<u32>,
    /// The compressed transfer matrix.
    pub codec: CodecBlob,
    /// Per mesh vertex, up to four (patch, weight) pairs in matrix order
    /// ([`crate::bake::mesh_map`]): weights ≥ 0 summing to 1, unused slots
    /// `(0, 0.0)`; a vertex no patch could light has four unused slots.
    pub mesh_map: Vec<[(u32, f32); 4]>,
    /// Free-form bake report, JSON text.
    pub info_json: String,
}

// ---------------------------------------------------------------------------
// Validation

fn invalid(file: &str, t: [u8; 4], detail: String) -> BakeFileError {
    BakeFileError::Invalid {
        file: file.to_string(),
        tag: tag_name(t),
        what: section_what(t),
        detail,
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

// ---------------------------------------------------------------------------
// Encoding

/// Rounds `x` up to a multiple of [`ALIGN`].
fn align_up(x: usize) -> usize {
    x.div_ceil(ALIGN) * ALIGN
}

/// The container layer: lays out `sections` (tag, bytes) in the given order
/// after the header and table, each at a multiple of [`ALIGN`] with zero
/// padding, and fills in every checksum and the file length. Does not look
/// at the contents; [`encode`] is the way to write a [`BakeFile`].
///
/// # Panics
/// With more than [`MAX_SECTIONS`] sections.
pub fn encode_sections(sections: &[([u8; 4], &[u8])]) -> Vec<u8> {
    assert!(
        sections.len() <= MAX_SECTIONS as usize,
        "{} sections exceed MAX_SECTIONS",
        sections.len()
    );
    let table_end = HEADER_LEN + ENTRY_LEN * sections.len();
    let mut offsets = Vec::with_capacity(sections.len());
    let mut end = table_end;
    for (_, body) in sections {
        let at = align_up(end);
        offsets.push(at);
        end = at + body.len();
    }
    let mut out = vec![0u8; end];
    out[0..8].copy_from_slice(&MAGIC);
    out[8..12].copy_from_slice(&FORMAT_VERSION.to_le_bytes());
    out[12..16].copy_from_slice(&0u32.to_le_bytes());
    out[16..24].copy_from_slice(&(end as u64).to_le_bytes());
    out[24..28].copy_from_slice(&(sections.len() as u32).to_le_bytes());
    for (i, ((t, body), &at)) in sections.iter().zip(&offsets).enumerate() {
        let e = HEADER_LEN + ENTRY_LEN * i;
        out[e..e + 4].copy_from_slice(t);
        out[e + 4..e + 8].copy_from_slice(&crc32(body).to_le_bytes());
        out[e + 8..e + 16].copy_from_slice(&(at as u64).to_le_bytes());
        out[e + 16..e + 24].copy_from_slice(&(body.len() as u64).to_le_bytes());
        out[at..at + body.len()].copy_from_slice(body);
    }
    let h = header_checksum(&out, table_end);
    out[28..32].copy_from_slice(&h.to_le_bytes());
    out
}

/// The header checksum of a file whose table ends at `table_end`: CRC-32 of
/// bytes `0..28` followed by bytes `32..table_end`.
pub fn header_checksum(bytes: &[u8], table_end: usize) -> u32 {
    let mut c = Crc32::new();
    c.update(&bytes[0..28]);
    c.update(&bytes[HEADER_LEN..table_end]);
    c.finish()
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
    for v in [bf.codec.kind, bf.codec.n, bf.codec.tile_size, 0] {
        codec.extend_from_slice(&v.to_le_bytes());
    }
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
    let sections: [([u8; 4], &[u8]); 12] = [
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
        (tag::MESH_MAP, &map),
        (tag::INFO, bf.info_json.as_bytes()),
    ];
    debug_assert!(sections.iter().map(|s| s.0).eq(tag::V1));
    Ok(encode_sections(&sections))
}

// ---------------------------------------------------------------------------
// Writing

/// Source of unique temporary names within this process.
static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// Writes `bf` to `path` atomically: the bytes go to a new temporary file in
/// the same directory (`.NAME.PID.K.tmp`, created exclusively), which is
/// flushed to disk and then renamed over `path`. Readers see the old file or
/// the complete new one, never a partial one; on failure the old file is
/// untouched and the temporary removed. An invalid `bf` is refused before
/// anything is written.
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
    let werr = |source| BakeFileError::Write {
        path: path.to_path_buf(),
        source,
    };
    let name = path.file_name().ok_or_else(|| {
        werr(io::Error::new(
            io::ErrorKind::InvalidInput,
            "the path does not name a file",
        ))
    })?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let tmp = dir.join(format!(
        ".{}.{}.{}.tmp",
        name.to_string_lossy(),
        std::process::id(),
        TEMP_COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    let result = (|| -> io::Result<()> {
        let mut f = File::options().write(true).create_new(true).open(&tmp)?;
        match fail_after {
            Some(k) => {
                f.write_all(&bytes[..k.min(bytes.len())])?;
                return Err(io::Error::other("injected write failure (test)"));
            }
            None => f.write_all(&bytes)?,
        }
        f.sync_all()?;
        drop(f);
        std::fs::rename(&tmp, path)
    })();
    if let Err(e) = result {
        // Best effort: the temporary may not exist if creating it failed.
        let _ = std::fs::remove_file(&tmp);
        return Err(werr(e));
    }
    // Make the rename itself durable. The rename already made the new file
    // visible atomically; syncing the directory only guards against power
    // loss, and some file systems refuse fsync on a directory, so a failure
    // here is not an error.
    if let Ok(d) = File::open(&dir) {
        let _ = d.sync_all();
    }
    Ok(())
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

/// One section of a file, as located by the table.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Section<'a> {
    pub tag: [u8; 4],
    /// Offset of the body in the file.
    pub offset: u64,
    pub bytes: &'a [u8],
}

fn le_u32(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

fn le_u64(b: &[u8], at: usize) -> u64 {
    let mut a = [0u8; 8];
    a.copy_from_slice(&b[at..at + 8]);
    u64::from_le_bytes(a)
}

/// The container layer of [`parse`]: checks the header, the table and every
/// section checksum, and returns the sections in table order (unknown tags
/// included). `file` names the input in messages.
pub fn sections<'a>(bytes: &'a [u8], file: &str) -> Result<Vec<Section<'a>>, BakeFileError> {
    let len = bytes.len();
    let file_s = || file.to_string();
    let truncated = |detail: String| BakeFileError::Truncated {
        file: file_s(),
        detail,
    };
    let header = |detail: String| BakeFileError::Header {
        file: file_s(),
        detail,
    };
    let table = |detail: String| BakeFileError::Table {
        file: file_s(),
        detail,
    };

    // Magic: a prefix of it is a truncated bake file, anything else is not one.
    let head = &bytes[..len.min(8)];
    if head != &MAGIC[..head.len()] {
        return Err(BakeFileError::NotABakeFile {
            file: file_s(),
            found: format!("{:?}", String::from_utf8_lossy(head)),
        });
    }
    if len < 12 {
        return Err(truncated(if len == 0 {
            "the file is empty".into()
        } else {
            format!("the file is {len} bytes, shorter than the {HEADER_LEN}-byte header")
        }));
    }
    // The version before anything else: a newer format may differ from here on.
    let version = le_u32(bytes, 8);
    if version > FORMAT_VERSION {
        return Err(BakeFileError::NewerVersion {
            file: file_s(),
            found: version,
            supported: FORMAT_VERSION,
        });
    }
    if version == 0 {
        return Err(BakeFileError::BadVersion {
            file: file_s(),
            found: version,
            supported: FORMAT_VERSION,
        });
    }
    if len < HEADER_LEN {
        return Err(truncated(format!(
            "the file is {len} bytes, shorter than the {HEADER_LEN}-byte header"
        )));
    }
    let count = le_u32(bytes, 24);
    if count > MAX_SECTIONS {
        return Err(header(format!(
            "section count {count} exceeds the limit of {MAX_SECTIONS} (corrupt header?)"
        )));
    }
    let table_end = HEADER_LEN + ENTRY_LEN * count as usize;
    if len < table_end {
        return Err(truncated(format!(
            "the section table of {count} entries needs {table_end} bytes, the file has {len}"
        )));
    }
    let stored = le_u32(bytes, 28);
    let computed = header_checksum(bytes, table_end);
    if stored != computed {
        return Err(BakeFileError::HeaderChecksum {
            file: file_s(),
            stored,
            computed,
        });
    }
    let declared = le_u64(bytes, 16);
    if (len as u64) < declared {
        return Err(truncated(format!(
            "the header declares {declared} bytes, the file has {len}"
        )));
    }
    if (len as u64) > declared {
        return Err(header(format!(
            "the header declares {declared} bytes but the file has {len}: trailing data"
        )));
    }
    let flags = le_u32(bytes, 12);
    if flags != 0 {
        return Err(header(format!(
            "flags {flags:#x} are set; format v{FORMAT_VERSION} defines none"
        )));
    }

    // The table: alignment and bounds, duplicates, overlaps, gaps.
    let mut entries: Vec<([u8; 4], u32, u64, u64)> = Vec::with_capacity(count as usize);
    for i in 0..count as usize {
        let e = HEADER_LEN + ENTRY_LEN * i;
        let t = [bytes[e], bytes[e + 1], bytes[e + 2], bytes[e + 3]];
        let crc = le_u32(bytes, e + 4);
        let offset = le_u64(bytes, e + 8);
        let length = le_u64(bytes, e + 16);
        let name = tag_name(t);
        if !offset.is_multiple_of(ALIGN as u64) {
            return Err(table(format!(
                "section {name} starts at offset {offset}, not a multiple of {ALIGN}"
            )));
        }
        match offset.checked_add(length) {
            Some(end) if offset >= table_end as u64 && end <= declared => {}
            _ => {
                return Err(table(format!(
                    "section {name} (offset {offset}, length {length}) lies outside the file's \
                     data area (bytes {table_end}..{declared})"
                )))
            }
        }
        if entries.iter().any(|p| p.0 == t) {
            return Err(table(format!("section {name} appears twice")));
        }
        entries.push((t, crc, offset, length));
    }
    let mut order: Vec<usize> = (0..entries.len()).collect();
    order.sort_by_key(|&i| (entries[i].2, entries[i].3));
    let mut cursor = table_end as u64;
    let mut previous: Option<usize> = None;
    for &i in &order {
        let (t, _, offset, length) = entries[i];
        if offset < cursor {
            // `previous` is set: offsets below the table end were rejected.
            let (pt, po, pl) = previous.map_or(([0; 4], 0, 0), |p| {
                (entries[p].0, entries[p].2, entries[p].3)
            });
            return Err(table(format!(
                "sections {} (bytes {po}..{}) and {} (bytes {offset}..{}) overlap",
                tag_name(pt),
                po + pl,
                tag_name(t),
                offset + length
            )));
        }
        check_gap(bytes, cursor, offset, &table)?;
        cursor = offset + length;
        previous = Some(i);
    }
    check_gap(bytes, cursor, declared, &table)?;

    // Every section's checksum, unknown sections included.
    let mut out = Vec::with_capacity(entries.len());
    for &(t, stored, offset, length) in &entries {
        let body = &bytes[offset as usize..(offset + length) as usize];
        let computed = crc32(body);
        if computed != stored {
            return Err(BakeFileError::SectionChecksum {
                file: file_s(),
                tag: tag_name(t),
                what: section_what(t),
                stored,
                computed,
            });
        }
        out.push(Section {
            tag: t,
            offset,
            bytes: body,
        });
    }
    Ok(out)
}

/// Checks the bytes `from..to` between two sections: alignment padding,
/// shorter than [`ALIGN`] and all zero.
fn check_gap(
    bytes: &[u8],
    from: u64,
    to: u64,
    table: &dyn Fn(String) -> BakeFileError,
) -> Result<(), BakeFileError> {
    if to - from >= ALIGN as u64 {
        return Err(table(format!(
            "bytes {from}..{to} belong to no section (more than alignment padding)"
        )));
    }
    if bytes[from as usize..to as usize].iter().any(|&b| b != 0) {
        return Err(table(format!("padding bytes {from}..{to} are not zero")));
    }
    Ok(())
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
    for t in tag::V1 {
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
    let permutation: Vec<u32> = multiple(tag::PERMUTATION, 4, "u32 entries")?
        .chunks_exact(4)
        .map(|c| le_u32(c, 0))
        .collect();
    let desc = exact(tag::CODEC, CODEC_DESCRIPTOR_LEN)?;
    if le_u32(desc, 12) != 0 {
        return Err(invalid(
            file,
            tag::CODEC,
            format!("reserved field is {}, must be 0", le_u32(desc, 12)),
        ));
    }
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
        mesh_map,
        info_json,
    };
    validate(&bf, file)?;
    Ok(bf)
}
