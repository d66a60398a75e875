//! The `.rad` bake file: round trips, determinism, atomic writes, and one
//! test per rejection rule of the reader (each checks that the message names
//! the cause), truncation at every byte, random corruption and arbitrary
//! bytes (proptest; `RADIOSITY_FUZZ_CASES` raises the case count for a long
//! run). Split by subject: this file holds the shared fixtures, checksums,
//! round trips and the header's and section table's rejections; `content`
//! the sections' contents, `corruption` random and arbitrary bytes,
//! `writes` atomic writes and the scene hash, `optional` the optional
//! sections (near field, column scales).

#[path = "../common/mod.rs"]
mod common;
mod content;
mod corruption;
mod optional;
mod writes;

use proptest::prelude::*;
use radiosity::bakefile::container::{encode_sections, header_checksum, ENTRY_LEN, HEADER_LEN};
use radiosity::bakefile::hash::Fnv1a64;
use radiosity::bakefile::near_field::{NearField, NearLink};
use radiosity::bakefile::surface::{PatchSamples, SurfaceMap};
use radiosity::bakefile::{
    self, crc32, encode, parse, tag, BakeFile, BakeFileError, CodecBlob, Crc32, PatchRecord,
    SceneHash, FORMAT_VERSION,
};
use std::path::Path;

/// A small valid bake file: 5 patches, 6 vertices.
fn sample() -> BakeFile {
    let patches: Vec<PatchRecord> = (0..5)
        .map(|i| {
            let f = i as f32;
            PatchRecord {
                centre: [f, 0.5 * f, -f],
                normal: [0.0, 1.0, 0.0],
                area: 0.25 + f,
                albedo: [0.5, 0.25, 0.125 * f],
                emission: [if i == 2 { 10.0 } else { 0.0 }; 3],
            }
        })
        .collect();
    let centres: Vec<([f32; 3], [f32; 3])> = patches.iter().map(|p| (p.centre, p.normal)).collect();
    BakeFile {
        options_json: r#"{"voxel_size":0.25,"bounces":"inf"}"#.into(),
        scene_hash: SceneHash {
            obj: 0x0123_4567_89ab_cdef,
            obj_len: 1234,
            mtl: 42,
            textures: 7,
        },
        permutation: vec![2, 0, 1, 4, 3],
        codec: CodecBlob {
            kind: 3,
            n: 5,
            tile_size: 32,
            params_json: r#"{"sparse_fraction":0.04,"L":25}"#.into(),
            scales: [1.5, 0.75, 0.0],
            dense: (0..40u8).collect(),
            tile_index: vec![9, 8, 7],
            sparse: vec![],
            col_scale: vec![],
        },
        mesh_map: vec![
            [(0, 1.0), (0, 0.0), (0, 0.0), (0, 0.0)],
            [(1, 0.5), (2, 0.25), (3, 0.125), (4, 0.125)],
            [(0, 0.0); 4],
            [(4, 0.75), (3, 0.25), (0, 0.0), (0, 0.0)],
            [(2, 0.6), (1, 0.4), (0, 0.0), (0, 0.0)],
            [(3, 1.0), (0, 0.0), (0, 0.0), (0, 0.0)],
        ],
        info_json: r#"{"report":"test","seconds":1.5}"#.into(),
        surface_map: SurfaceMap::without_geometry(5),
        samples: PatchSamples::at_centres(&centres),
        near_field: NearField::default(),
        sky: Default::default(),
        probes: Default::default(),
        patches,
    }
}

/// The error message of parsing `bytes`, which must fail.
fn reject(bytes: &[u8]) -> (BakeFileError, String) {
    match parse(bytes) {
        Ok(_) => panic!("parse accepted invalid bytes"),
        Err(e) => {
            let m = e.to_string();
            (e, m)
        }
    }
}

/// The sections of a valid file as (tag, bytes), to rebuild variants.
fn sections_of(bytes: &[u8]) -> Vec<([u8; 4], Vec<u8>)> {
    bakefile::sections(bytes, "test")
        .unwrap()
        .into_iter()
        .map(|s| (s.tag, s.bytes.to_vec()))
        .collect()
}

/// Re-encodes with one section's bytes replaced (checksums valid).
fn with_section(t: [u8; 4], f: impl FnOnce(&mut Vec<u8>)) -> Vec<u8> {
    let mut secs = sections_of(&encode(&sample()).unwrap());
    let s = secs.iter_mut().find(|s| s.0 == t).expect("section present");
    f(&mut s.1);
    let refs: Vec<([u8; 4], &[u8])> = secs.iter().map(|(t, b)| (*t, b.as_slice())).collect();
    encode_sections(&refs)
}

/// Recomputes the header checksum after editing the header or table.
fn reseal(bytes: &mut [u8]) {
    let count = u32::from_le_bytes(bytes[24..28].try_into().unwrap()) as usize;
    let h = header_checksum(bytes, HEADER_LEN + ENTRY_LEN * count);
    bytes[28..32].copy_from_slice(&h.to_le_bytes());
}

/// Byte position of table entry `i`'s field at `field` (0 tag, 4 crc,
/// 8 offset, 16 length).
fn entry(i: usize, field: usize) -> usize {
    HEADER_LEN + ENTRY_LEN * i + field
}

fn index_of(bytes: &[u8], t: [u8; 4]) -> usize {
    let count = u32::from_le_bytes(bytes[24..28].try_into().unwrap()) as usize;
    (0..count)
        .find(|&i| bytes[entry(i, 0)..entry(i, 4)] == t)
        .unwrap()
}

fn put_u64(bytes: &mut [u8], at: usize, v: u64) {
    bytes[at..at + 8].copy_from_slice(&v.to_le_bytes());
}

fn set_f32(b: &mut [u8], at: usize, v: f32) {
    b[at..at + 4].copy_from_slice(&v.to_le_bytes());
}

fn set_u32(b: &mut [u8], at: usize, v: u32) {
    b[at..at + 4].copy_from_slice(&v.to_le_bytes());
}

fn get_u64(bytes: &[u8], at: usize) -> u64 {
    u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap())
}

// ---------------------------------------------------------------------------
// Checksums

/// Bit-at-a-time CRC-32, the textbook definition, as the reference for the
/// table-driven one.
fn crc32_bitwise(bytes: &[u8]) -> u32 {
    let mut c = !0u32;
    for &b in bytes {
        c ^= b as u32;
        for _ in 0..8 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
    }
    !c
}

#[test]
fn crc32_matches_the_standard_check_value_and_the_bitwise_definition() {
    assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
    assert_eq!(crc32(b""), 0);
    let data: Vec<u8> = (0..1000u32)
        .map(|i| (i.wrapping_mul(2654435761) >> 13) as u8)
        .collect();
    for len in (0..200).chain([999, 1000]) {
        assert_eq!(
            crc32(&data[..len]),
            crc32_bitwise(&data[..len]),
            "length {len}"
        );
    }
    // Streaming in uneven pieces gives the same value.
    let mut c = Crc32::new();
    for piece in data.chunks(13) {
        c.update(piece);
    }
    assert_eq!(c.finish(), crc32(&data));
}

#[test]
fn fnv1a64_matches_published_test_vectors() {
    // From the reference test suite of Fowler, Noll and Vo (fnv_test.c).
    let h = |s: &[u8]| {
        let mut f = Fnv1a64::new();
        f.update(s);
        f.finish()
    };
    assert_eq!(h(b""), 0xcbf2_9ce4_8422_2325);
    assert_eq!(h(b"a"), 0xaf63_dc4c_8601_ec8c);
    assert_eq!(h(b"foobar"), 0x8594_4171_f739_67e8);
}

// ---------------------------------------------------------------------------
// Round trip, determinism, layout

#[test]
fn round_trip_in_memory_and_on_disk() {
    let bf = sample();
    let bytes = encode(&bf).unwrap();
    assert_eq!(parse(&bytes).unwrap(), bf);
    let dir = common::temp_dir("bakefile-roundtrip");
    let path = dir.join("scene.rad");
    bakefile::write(&path, &bf).unwrap();
    assert_eq!(bakefile::read(&path).unwrap(), bf);
    assert_eq!(std::fs::read(&path).unwrap(), bytes);
    // An empty bake (no patches, no vertices) round-trips too.
    let empty = BakeFile {
        options_json: "{}".into(),
        codec: CodecBlob {
            params_json: "null".into(),
            ..Default::default()
        },
        info_json: "[]".into(),
        ..Default::default()
    };
    assert_eq!(parse(&encode(&empty).unwrap()).unwrap(), empty);
}

#[test]
fn layout_matches_the_documented_header() {
    let bytes = encode(&sample()).unwrap();
    assert_eq!(&bytes[0..8], b"RADBAKE\0");
    assert_eq!(
        u32::from_le_bytes(bytes[8..12].try_into().unwrap()),
        FORMAT_VERSION
    );
    assert_eq!(get_u64(&bytes, 16), bytes.len() as u64);
    assert_eq!(
        u32::from_le_bytes(bytes[24..28].try_into().unwrap()) as usize,
        tag::REQUIRED.len()
    );
    let secs = bakefile::sections(&bytes, "test").unwrap();
    assert_eq!(
        secs.iter().map(|s| s.tag).collect::<Vec<_>>(),
        tag::REQUIRED
    );
    for s in &secs {
        assert_eq!(s.offset % 8, 0, "{} is aligned", bakefile::tag_name(s.tag));
    }
    let patches = secs.iter().find(|s| s.tag == tag::PATCHES).unwrap();
    assert_eq!(patches.bytes.len(), 5 * bakefile::PATCH_RECORD_LEN);
    let map = secs.iter().find(|s| s.tag == tag::MESH_MAP).unwrap();
    assert_eq!(map.bytes.len(), 6 * bakefile::MAP_ENTRY_LEN);
}

#[test]
fn encoding_is_deterministic() {
    let a = encode(&sample()).unwrap();
    let b = encode(&sample().clone()).unwrap();
    assert_eq!(a, b);
    let dir = common::temp_dir("bakefile-determinism");
    bakefile::write(&dir.join("a.rad"), &sample()).unwrap();
    bakefile::write(&dir.join("b.rad"), &sample()).unwrap();
    assert_eq!(
        std::fs::read(dir.join("a.rad")).unwrap(),
        std::fs::read(dir.join("b.rad")).unwrap()
    );
}

#[test]
fn unknown_sections_are_checked_and_ignored() {
    let bytes = encode(&sample()).unwrap();
    let mut secs = sections_of(&bytes);
    secs.insert(3, (*b"XTRA", b"future data".to_vec()));
    let refs: Vec<([u8; 4], &[u8])> = secs.iter().map(|(t, b)| (*t, b.as_slice())).collect();
    let mut extended = encode_sections(&refs);
    assert_eq!(parse(&extended).unwrap(), sample());
    // ... but their checksum is still verified.
    let s = bakefile::sections(&extended, "t").unwrap()[3].offset as usize;
    extended[s] ^= 1;
    let (_, m) = reject(&extended);
    assert!(
        m.contains("section XTRA") && m.contains("checksum mismatch"),
        "{m}"
    );
}

// ---------------------------------------------------------------------------
// Header rejections

#[test]
fn rejects_wrong_magic() {
    let mut bytes = encode(&sample()).unwrap();
    bytes[0] = b'X';
    let (e, m) = reject(&bytes);
    assert!(matches!(e, BakeFileError::NotABakeFile { .. }), "{m}");
    assert!(m.contains("not a radiosity bake file"), "{m}");
    let (_, m) = reject(b"# an OBJ file\nv 0 0 0\n");
    assert!(m.contains("not a radiosity bake file"), "{m}");
}

#[test]
fn rejects_a_newer_version_with_a_clear_message() {
    let mut bytes = encode(&sample()).unwrap();
    let newer = FORMAT_VERSION + 1;
    bytes[8..12].copy_from_slice(&newer.to_le_bytes());
    // Whatever follows the version is not looked at (it may be a new layout).
    bytes[40..].iter_mut().for_each(|b| *b = 0xAA);
    let (e, m) = reject(&bytes);
    assert!(
        matches!(e, BakeFileError::NewerVersion { found, .. } if found == newer),
        "{m}"
    );
    assert!(
        m.ends_with(&format!(
            "written by a newer radiosity (format v{newer}); this build reads v{FORMAT_VERSION}"
        )),
        "{m}"
    );
    // An older version is refused before its layout is read, asking for a
    // new bake.
    bytes[8..12].copy_from_slice(&1u32.to_le_bytes());
    let (e, m) = reject(&bytes);
    assert!(
        matches!(e, BakeFileError::OlderVersion { found: 1, .. }),
        "{m}"
    );
    assert!(
        m.contains("older radiosity (format v1)") && m.contains("bake the scene again"),
        "{m}"
    );
    bytes[8..12].copy_from_slice(&0u32.to_le_bytes());
    let (_, m) = reject(&bytes);
    assert!(m.contains("format version 0 does not exist"), "{m}");
}

#[test]
fn rejects_truncation_at_every_byte() {
    let bytes = encode(&sample()).unwrap();
    for len in 0..bytes.len() {
        match parse(&bytes[..len]) {
            Err(BakeFileError::Truncated { detail, .. }) => {
                if len == 0 {
                    assert!(detail.contains("empty"), "{detail}");
                }
                if len >= HEADER_LEN + tag::REQUIRED.len() * ENTRY_LEN {
                    assert!(
                        detail.contains(&format!(
                            "the header declares {} bytes, the file has {len}",
                            bytes.len()
                        )),
                        "{detail}"
                    );
                }
            }
            other => panic!("prefix of {len} bytes: expected a truncation error, got {other:?}"),
        }
    }
}

#[test]
fn rejects_trailing_data() {
    let mut bytes = encode(&sample()).unwrap();
    bytes.extend_from_slice(&[0; 3]);
    let (_, m) = reject(&bytes);
    assert!(m.contains("trailing data"), "{m}");
}

#[test]
fn rejects_header_checksum_mismatch() {
    let bytes = encode(&sample()).unwrap();
    // A flipped bit in a table entry (a section's CRC field)...
    let mut b = bytes.clone();
    b[entry(5, 4)] ^= 0x10;
    let (e, m) = reject(&b);
    assert!(matches!(e, BakeFileError::HeaderChecksum { .. }), "{m}");
    assert!(m.contains("header checksum mismatch"), "{m}");
    // ... and in the stored checksum itself.
    let mut b = bytes.clone();
    b[29] ^= 1;
    assert!(matches!(reject(&b).0, BakeFileError::HeaderChecksum { .. }));
}

#[test]
fn rejects_unknown_flags() {
    let mut bytes = encode(&sample()).unwrap();
    bytes[12] = 1;
    reseal(&mut bytes);
    let (_, m) = reject(&bytes);
    assert!(m.contains("header: flags 0x1"), "{m}");
}

#[test]
fn rejects_an_absurd_section_count_without_allocating() {
    let mut bytes = encode(&sample()).unwrap();
    bytes[24..28].copy_from_slice(&u32::MAX.to_le_bytes());
    let (_, m) = reject(&bytes);
    assert!(
        m.contains("section count 4294967295 exceeds the limit"),
        "{m}"
    );
    // A count within the limit whose table does not fit is a truncation.
    bytes[24..28].copy_from_slice(&200u32.to_le_bytes());
    let (e, m) = reject(&bytes);
    assert!(matches!(e, BakeFileError::Truncated { .. }), "{m}");
    assert!(m.contains("section table of 200 entries"), "{m}");
}

// ---------------------------------------------------------------------------
// Table rejections

#[test]
fn rejects_a_section_out_of_bounds() {
    let mut bytes = encode(&sample()).unwrap();
    let i = index_of(&bytes, tag::PATCHES);
    // An absurd length (no allocation is made from it).
    put_u64(&mut bytes, entry(i, 16), u64::MAX - 3);
    reseal(&mut bytes);
    let (e, m) = reject(&bytes);
    assert!(matches!(e, BakeFileError::Table { .. }), "{m}");
    assert!(
        m.contains("section PTCH") && m.contains("lies outside"),
        "{m}"
    );
    // An offset inside the header.
    let mut bytes = encode(&sample()).unwrap();
    put_u64(&mut bytes, entry(i, 8), 8);
    reseal(&mut bytes);
    let (_, m) = reject(&bytes);
    assert!(
        m.contains("section PTCH") && m.contains("lies outside"),
        "{m}"
    );
}

#[test]
fn rejects_overlapping_sections() {
    let mut bytes = encode(&sample()).unwrap();
    let a = index_of(&bytes, tag::PATCHES);
    let b = index_of(&bytes, tag::PERMUTATION);
    // Point PERM into the middle of PTCH.
    let ptch = get_u64(&bytes, entry(a, 8));
    put_u64(&mut bytes, entry(b, 8), ptch + 8);
    reseal(&mut bytes);
    let (_, m) = reject(&bytes);
    assert!(
        m.contains("sections PTCH") && m.contains("and PERM") && m.contains("overlap"),
        "{m}"
    );
}

#[test]
fn rejects_a_duplicated_section() {
    let mut bytes = encode(&sample()).unwrap();
    let i = index_of(&bytes, tag::SPARSE);
    bytes[entry(i, 0)..entry(i, 4)].copy_from_slice(&tag::DENSE);
    reseal(&mut bytes);
    let (_, m) = reject(&bytes);
    assert!(m.contains("section DENS appears twice"), "{m}");
}

#[test]
fn rejects_a_missing_required_section() {
    for missing in tag::REQUIRED {
        let secs = sections_of(&encode(&sample()).unwrap());
        let refs: Vec<([u8; 4], &[u8])> = secs
            .iter()
            .filter(|s| s.0 != missing)
            .map(|(t, b)| (*t, b.as_slice()))
            .collect();
        let (e, m) = reject(&encode_sections(&refs));
        assert!(matches!(e, BakeFileError::MissingSection { .. }), "{m}");
        assert!(
            m.contains(&format!(
                "missing required section {}",
                bakefile::tag_name(missing)
            )),
            "{m}"
        );
    }
}

#[test]
fn rejects_misaligned_sections_and_hidden_bytes() {
    let bytes = encode(&sample()).unwrap();
    let i = index_of(&bytes, tag::INFO);
    let mut b = bytes.clone();
    let off = get_u64(&b, entry(i, 8));
    put_u64(&mut b, entry(i, 8), off + 1);
    put_u64(&mut b, entry(i, 16), get_u64(&bytes, entry(i, 16)) - 1);
    reseal(&mut b);
    let (_, m) = reject(&b);
    assert!(m.contains("not a multiple of 8"), "{m}");
    // Non-zero padding between two sections (OPTS is 35 bytes: 5 of padding).
    let mut b = bytes.clone();
    let o = index_of(&b, tag::OPTIONS);
    let end = (get_u64(&b, entry(o, 8)) + get_u64(&b, entry(o, 16))) as usize;
    assert_eq!(end % 8, 3, "the sample's options leave padding");
    b[end] = 0x55;
    let (_, m) = reject(&b);
    assert!(m.contains("padding bytes") && m.contains("not zero"), "{m}");
    // A shortened section leaves more than alignment padding unaccounted for.
    let mut b = bytes.clone();
    let d = index_of(&b, tag::DENSE);
    put_u64(&mut b, entry(d, 16), 16);
    let crc = crc32(&b[get_u64(&b, entry(d, 8)) as usize..][..16]);
    b[entry(d, 4)..entry(d, 8)].copy_from_slice(&crc.to_le_bytes());
    reseal(&mut b);
    let (_, m) = reject(&b);
    assert!(m.contains("belong to no section"), "{m}");
}

#[test]
fn rejects_section_checksum_mismatch() {
    let mut bytes = encode(&sample()).unwrap();
    let secs = bakefile::sections(&bytes, "t").unwrap();
    let p = secs.iter().find(|s| s.tag == tag::PATCHES).unwrap().offset as usize;
    bytes[p + 7] ^= 0x20;
    let (e, m) = reject(&bytes);
    assert!(matches!(e, BakeFileError::SectionChecksum { .. }), "{m}");
    assert!(
        m.contains("section PTCH (patches): checksum mismatch"),
        "{m}"
    );
}
