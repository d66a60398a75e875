//! The container layer of the bake file: magic, version, header, a table
//! of tagged sections each with its CRC-32, alignment, and the atomic
//! write. It does not look inside sections; [`super`] defines them (the
//! module doc there gives the byte layout).

use super::section_what;
use std::fs::File;
use std::io::{self, Read, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// The first 8 bytes of every bake file.
pub const MAGIC: [u8; 8] = *b"RADBAKE\0";

/// The format version this build writes and reads.
pub const FORMAT_VERSION: u32 = 2;

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
/// `(in-memory bake file)` for `parse`) and the section or field at fault.
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
    #[error(
        "{file}: written by an older radiosity (format v{found}); this build reads v{supported} \
         only: bake the scene again"
    )]
    OlderVersion {
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
        detail: crate::SectionError,
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

/// Rounds `x` up to a multiple of [`ALIGN`].
fn align_up(x: usize) -> usize {
    x.div_ceil(ALIGN) * ALIGN
}

/// The container layer: lays out `sections` (tag, bytes) in the given order
/// after the header and table, each at a multiple of [`ALIGN`] with zero
/// padding, and fills in every checksum and the file length. Does not look
/// at the contents; `encode` is the way to write a `BakeFile`.
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

/// Source of unique temporary names within this process.
static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// Writes `bytes` to `path` atomically: they go to a new temporary file in
/// the same directory (`.NAME.PID.K.tmp`, created exclusively), which is
/// flushed to disk (`fsync`) and then renamed over `path`. Readers see the
/// old file or the complete new one, never a partial one; on failure the
/// old file is untouched and the temporary removed. Used for bake files and
/// for every report the binary writes. `fail_after` (tests only) makes the
/// temporary's write fail after that many bytes, as a full disk would.
pub fn write_atomic(path: &Path, bytes: &[u8], fail_after: Option<usize>) -> io::Result<()> {
    let name = path.file_name().ok_or_else(|| {
        io::Error::new(io::ErrorKind::InvalidInput, "the path does not name a file")
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
            None => f.write_all(bytes)?,
        }
        f.sync_all()?;
        drop(f);
        std::fs::rename(&tmp, path)
    })();
    if let Err(e) = result {
        // Best effort: the temporary may not exist if creating it failed.
        let _ = std::fs::remove_file(&tmp);
        return Err(e);
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

/// One section of a file, as located by the table.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Section<'a> {
    pub tag: [u8; 4],
    /// Offset of the body in the file.
    pub offset: u64,
    pub bytes: &'a [u8],
}

pub fn le_u32(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

pub fn le_u64(b: &[u8], at: usize) -> u64 {
    let mut a = [0u8; 8];
    a.copy_from_slice(&b[at..at + 8]);
    u64::from_le_bytes(a)
}

/// The container layer of `parse`: checks the header, the table and every
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
    if (1..FORMAT_VERSION).contains(&version) {
        return Err(BakeFileError::OlderVersion {
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
