//! The `.rad` bake file: round trips, determinism, atomic writes, and one
//! test per rejection rule of the reader (each checks that the message names
//! the cause), truncation at every byte, random corruption and arbitrary
//! bytes (proptest; `RADIOSITY_FUZZ_CASES` raises the case count for a long
//! run).

mod common;

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

// ---------------------------------------------------------------------------
// Content rejections (checksums valid: what a buggy writer would produce)

fn reject_section(t: [u8; 4], f: impl FnOnce(&mut Vec<u8>), expect: &[&str]) {
    let (e, m) = reject(&with_section(t, f));
    assert!(matches!(e, BakeFileError::Invalid { .. }), "{m}");
    for want in expect {
        assert!(m.contains(want), "message {m:?} lacks {want:?}");
    }
}

fn set_f32(b: &mut [u8], at: usize, v: f32) {
    b[at..at + 4].copy_from_slice(&v.to_le_bytes());
}

fn set_u32(b: &mut [u8], at: usize, v: u32) {
    b[at..at + 4].copy_from_slice(&v.to_le_bytes());
}

#[test]
fn rejects_patch_section_with_partial_record() {
    reject_section(
        tag::PATCHES,
        |b| b.truncate(b.len() - 4),
        &[
            "section PTCH (patches)",
            "not a whole number of 52-byte patch records",
        ],
    );
}

#[test]
fn rejects_invalid_patch_values() {
    reject_section(
        tag::PATCHES,
        |b| set_f32(b, 52 + 4, f32::NAN),
        &["section PTCH", "patch 1: centre is not finite"],
    );
    reject_section(
        tag::PATCHES,
        |b| set_f32(b, 16, 1.5),
        &["patch 0: normal has length"],
    );
    reject_section(
        tag::PATCHES,
        |b| set_f32(b, 24, 0.0),
        &["patch 0: area is not positive"],
    );
    reject_section(
        tag::PATCHES,
        |b| set_f32(b, 2 * 52 + 28, 1.0),
        &["patch 2: albedo is outside [0, 1)"],
    );
    reject_section(
        tag::PATCHES,
        |b| set_f32(b, 3 * 52 + 40, -1.0),
        &["patch 3: emission is negative"],
    );
}

#[test]
fn rejects_a_permutation_that_is_not_one() {
    reject_section(
        tag::PERMUTATION,
        |b| set_u32(b, 4, 2),
        &[
            "section PERM (permutation)",
            "patch 2 appears twice",
            "not a permutation of 0..5",
        ],
    );
    reject_section(
        tag::PERMUTATION,
        |b| set_u32(b, 0, 5),
        &["entry 0 is 5, outside 0..5"],
    );
    reject_section(
        tag::PERMUTATION,
        |b| b.truncate(8),
        &["2 entries for 5 patches"],
    );
    reject_section(
        tag::PERMUTATION,
        |b| b.push(0),
        &["not a whole number of 4-byte u32 entries"],
    );
}

#[test]
fn rejects_mesh_map_index_out_of_range() {
    reject_section(
        tag::MESH_MAP,
        |b| set_u32(b, 32 + 8, 5),
        &[
            "section MMAP (mesh-to-patch map)",
            "vertex 1, slot 1",
            "patch index 5 is out of range",
        ],
    );
    reject_section(
        tag::MESH_MAP,
        |b| set_u32(b, 8, 3),
        &[
            "vertex 0, slot 1",
            "unused slot (weight 0) must have patch 0",
        ],
    );
}

#[test]
fn rejects_mesh_map_weights_not_finite_or_not_summing_to_one() {
    reject_section(
        tag::MESH_MAP,
        |b| set_f32(b, 4, f32::NAN),
        &["vertex 0, slot 0", "weight NaN is not a finite number"],
    );
    reject_section(
        tag::MESH_MAP,
        |b| set_f32(b, 32 + 4, f32::INFINITY),
        &["vertex 1, slot 0", "weight inf"],
    );
    reject_section(
        tag::MESH_MAP,
        |b| set_f32(b, 32 + 4, -0.5),
        &["weight -0.5 is not a finite number ≥ 0"],
    );
    reject_section(
        tag::MESH_MAP,
        |b| set_f32(b, 3 * 32 + 4, 0.7),
        &["vertex 3: weights sum to 0.94999", "not 1"],
    );
    reject_section(
        tag::MESH_MAP,
        |b| b.truncate(b.len() - 8),
        &["not a whole number of 32-byte vertex entries"],
    );
}

#[test]
fn rejects_json_sections_that_are_not_utf8_or_not_json() {
    reject_section(
        tag::OPTIONS,
        |b| b[3] = 0xFF,
        &["section OPTS (bake options)", "not valid UTF-8"],
    );
    reject_section(
        tag::INFO,
        |b| b.truncate(b.len() - 1),
        &["section INFO (bake report)", "not valid JSON"],
    );
    reject_section(
        tag::CODEC_PARAMS,
        |b| *b = b"{} trailing".to_vec(),
        &["section CPRM (codec parameters)", "not valid JSON"],
    );
    // Deep nesting is an error, not a stack overflow.
    reject_section(
        tag::INFO,
        |b| *b = "[".repeat(100_000).into_bytes(),
        &["section INFO", "not valid JSON"],
    );
}

#[test]
fn rejects_inconsistent_codec_descriptor_and_scales() {
    reject_section(
        tag::CODEC,
        |b| set_u32(b, 4, 6),
        &[
            "section CDSC (codec descriptor)",
            "field n is 6 but the file holds 5 patches",
        ],
    );
    reject_section(
        tag::CODEC,
        |b| set_u32(b, 12, 2),
        &["section CDSC", "flags are 0x2"],
    );
    reject_section(
        tag::CODEC,
        |b| set_u32(b, 12, 1),
        &["section CDSC", "flag bit 0", "no CCOL section"],
    );
    reject_section(
        tag::CODEC,
        |b| b.push(0),
        &["section CDSC", "17 bytes, expected exactly 16"],
    );
    reject_section(
        tag::SCALES,
        |b| set_f32(b, 8, -1.0),
        &["section SCAL (channel scales)", "channel B scale is -1"],
    );
    reject_section(
        tag::SCENE_HASH,
        |b| b.truncate(31),
        &["section SRCH (scene hash)", "31 bytes, expected exactly 32"],
    );
}

#[test]
fn writer_refuses_what_the_reader_would_reject() {
    let mut bf = sample();
    bf.mesh_map[1][0].1 = 0.9;
    let e = encode(&bf).unwrap_err().to_string();
    assert!(
        e.starts_with("refusing to write an invalid bake file"),
        "{e}"
    );
    assert!(e.contains("vertex 1: weights sum to"), "{e}");
    let dir = common::temp_dir("bakefile-refuse");
    let path = dir.join("x.rad");
    let e = bakefile::write(&path, &bf).unwrap_err().to_string();
    assert!(e.contains(&path.display().to_string()), "{e}");
    assert!(!path.exists());
    assert_eq!(
        std::fs::read_dir(&dir).unwrap().count(),
        0,
        "nothing written"
    );
}

// ---------------------------------------------------------------------------
// Corruption, arbitrary bytes

/// xorshift64*: a tiny deterministic generator for the corruption tests.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

#[test]
fn random_byte_changes_are_always_detected() {
    let bytes = encode(&sample()).unwrap();
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    // Every single-byte change at every position, with a random new value.
    for at in 0..bytes.len() {
        let mut b = bytes.clone();
        b[at] ^= 1 + rng.below(255) as u8;
        assert!(parse(&b).is_err(), "change at byte {at} went unnoticed");
    }
    // Multi-byte changes.
    for trial in 0..5000 {
        let mut b = bytes.clone();
        for _ in 0..1 + rng.below(8) {
            let at = rng.below(b.len());
            b[at] ^= 1 + rng.below(255) as u8;
        }
        if b != bytes {
            assert!(
                parse(&b).is_err(),
                "trial {trial}: corruption went unnoticed"
            );
        }
    }
}

#[test]
fn reading_a_corrupt_file_names_it() {
    let dir = common::temp_dir("bakefile-corrupt");
    let path = dir.join("corrupt.rad");
    let mut bytes = encode(&sample()).unwrap();
    let n = bytes.len();
    bytes[n - 5] ^= 0xFF;
    std::fs::write(&path, &bytes).unwrap();
    let e = bakefile::read(&path).unwrap_err().to_string();
    assert!(e.starts_with(&path.display().to_string()), "{e}");
    assert!(
        e.contains("section INFO (bake report): checksum mismatch"),
        "{e}"
    );
    let e = bakefile::read(&dir.join("missing.rad"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("cannot read bake file") && e.contains("missing.rad"),
        "{e}"
    );
}

/// Proptest case count: `RADIOSITY_FUZZ_CASES` (default 1000).
fn cases() -> u32 {
    std::env::var("RADIOSITY_FUZZ_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1000)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(), failure_persistence: None, ..ProptestConfig::default() })]

    /// Arbitrary bytes never panic; most are rejected at the magic.
    #[test]
    fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..512)) {
        let _ = parse(&bytes);
    }

    /// Arbitrary bytes behind a valid magic and version reach the deeper
    /// checks, and never panic.
    #[test]
    fn arbitrary_bytes_after_a_valid_header_prefix_never_panic(
        tail in proptest::collection::vec(any::<u8>(), 0..1024),
    ) {
        let mut bytes = b"RADBAKE\0\x01\0\0\0".to_vec();
        bytes.extend_from_slice(&tail);
        prop_assert!(parse(&bytes).is_err());
    }

    /// Structured garbage: a valid file whose table has been rewritten with
    /// arbitrary entries, resealed so that the header checksum passes.
    #[test]
    fn arbitrary_tables_never_panic(
        edits in proptest::collection::vec((0usize..12, 0usize..24, any::<u8>()), 1..6),
    ) {
        let mut bytes = encode(&sample()).unwrap();
        for (i, f, v) in edits {
            bytes[entry(i, f)] = v;
        }
        reseal(&mut bytes);
        let _ = parse(&bytes);
    }

    /// Valid contents of any shape round-trip exactly.
    #[test]
    fn valid_files_round_trip(
        n in 0usize..6,
        rows in proptest::collection::vec((0u32..1000, 1u32..1000), 0..8),
        dense in proptest::collection::vec(any::<u8>(), 0..64),
        seed in any::<u64>(),
    ) {
        let mut rng = Rng(seed | 1);
        let mut bf = sample();
        bf.patches.truncate(n);
        bf.surface_map = SurfaceMap::without_geometry(n);
        bf.samples.position.truncate(n * radiosity::bakefile::surface::SAMPLES_PER_PATCH);
        bf.samples.normal.truncate(n * radiosity::bakefile::surface::SAMPLES_PER_PATCH);
        let mut perm: Vec<u32> = (0..n as u32).collect();
        for i in (1..n).rev() {
            perm.swap(i, rng.below(i + 1));
        }
        bf.permutation = perm;
        bf.codec.n = n as u32;
        bf.codec.dense = dense;
        bf.mesh_map = rows
            .iter()
            .map(|&(p, w)| {
                if n == 0 {
                    [(0, 0.0); 4]
                } else {
                    let a = w as f32 / 1000.0;
                    let q = p % n as u32;
                    if a < 1.0 { [(q, a), ((q + 1) % n as u32, 1.0 - a), (0, 0.0), (0, 0.0)] }
                    else { [(q, 1.0), (0, 0.0), (0, 0.0), (0, 0.0)] }
                }
            })
            .collect();
        let bytes = encode(&bf).unwrap();
        prop_assert_eq!(parse(&bytes).unwrap(), bf);
    }
}

// ---------------------------------------------------------------------------
// Atomic writes

fn leftovers(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".tmp"))
        .collect()
}

#[test]
fn a_failed_write_leaves_the_old_file_and_no_temporary() {
    let dir = common::temp_dir("bakefile-atomic");
    let path = dir.join("scene.rad");
    let old = sample();
    bakefile::write(&path, &old).unwrap();
    let old_bytes = std::fs::read(&path).unwrap();
    let mut new = sample();
    new.info_json = r#"{"report":"second bake"}"#.into();
    let len = encode(&new).unwrap().len();
    for fail_after in [0, 1, 100, len / 2, len - 1, len] {
        let e = bakefile::write_failing_after(&path, &new, fail_after).unwrap_err();
        assert!(e.to_string().contains("cannot write bake file"), "{e}");
        assert_eq!(std::fs::read(&path).unwrap(), old_bytes, "old file intact");
        assert!(
            leftovers(&dir).is_empty(),
            "temporary removed: {:?}",
            leftovers(&dir)
        );
    }
    bakefile::write(&path, &new).unwrap();
    assert_eq!(bakefile::read(&path).unwrap(), new);
    assert!(leftovers(&dir).is_empty());
    // A directory that does not exist: an error naming the path.
    let e = bakefile::write(&dir.join("no/such/dir/x.rad"), &new)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("cannot write bake file") && e.contains("no/such/dir/x.rad"),
        "{e}"
    );
}

#[test]
fn concurrent_readers_see_the_old_or_the_new_file_never_a_partial_one() {
    let dir = common::temp_dir("bakefile-concurrent");
    let path = dir.join("scene.rad");
    let a = sample();
    let mut b = sample();
    // A larger second version, so a partial write would be visible.
    b.codec.dense = vec![7; 200_000];
    bakefile::write(&path, &a).unwrap();
    let stop = std::sync::atomic::AtomicBool::new(false);
    std::thread::scope(|s| {
        let reader = s.spawn(|| {
            let mut reads = 0u32;
            while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                let got = bakefile::read(&path).expect("every read sees a whole file");
                assert!(got == a || got == b);
                reads += 1;
            }
            reads
        });
        for i in 0..60 {
            bakefile::write(&path, if i % 2 == 0 { &b } else { &a }).unwrap();
        }
        stop.store(true, std::sync::atomic::Ordering::Relaxed);
        let reads = reader.join().unwrap();
        assert!(reads > 0);
    });
    assert!(leftovers(&dir).is_empty());
}

// ---------------------------------------------------------------------------
// Scene hash

#[test]
fn scene_hash_follows_the_obj_and_mtl_contents() {
    let q = common::quad(
        [0.0; 3],
        [1.0, 0.0, 0.0],
        [0.0, 0.0, -1.0],
        1.0,
        1.0,
        [0.5; 3],
    );
    let obj = common::write_quads("bakefile-hash", &[q]);
    let scene = radiosity::core::scene::load(&obj).unwrap();
    let h1 = SceneHash::of_scene(&scene).unwrap();
    assert_eq!(h1, SceneHash::of_scene(&scene).unwrap(), "deterministic");
    assert_eq!(h1.obj_len, std::fs::metadata(&obj).unwrap().len());
    let mut f = Fnv1a64::new();
    f.update(&std::fs::read(&obj).unwrap());
    assert_eq!(h1.obj, f.finish());
    // Changing the MTL changes only its part.
    let mtl = obj.with_file_name("scene.mtl");
    let text = std::fs::read_to_string(&mtl).unwrap();
    std::fs::write(&mtl, text.replace("Kd 0.5", "Kd 0.6")).unwrap();
    let h2 = SceneHash::of_scene(&scene).unwrap();
    assert_eq!(h2.differences(&h1), vec!["mtl"]);
    // Changing the OBJ changes its part.
    let text = std::fs::read_to_string(&obj).unwrap();
    std::fs::write(&obj, format!("{text}# comment\n")).unwrap();
    let h3 = SceneHash::of_scene(&scene).unwrap();
    assert_eq!(h3.differences(&h2), vec!["obj"]);
    // The hash round-trips through the file.
    let mut bf = sample();
    bf.scene_hash = h3;
    assert_eq!(parse(&encode(&bf).unwrap()).unwrap().scene_hash, h3);
}

/// The sample file with a near-field correction: patch 0 sees patches 1
/// and 3, patch 4 sees patch 0, 64 rays each.
fn with_near_field() -> BakeFile {
    let mut counts = [0u16; 16];
    counts[0] = 5;
    counts[15] = 3;
    BakeFile {
        near_field: NearField {
            rays: 64,
            starts: vec![0, 2, 2, 2, 2, 3],
            links: vec![
                NearLink { patch: 1, counts },
                NearLink {
                    patch: 3,
                    counts: [1; 16],
                },
                NearLink { patch: 0, counts },
            ],
            shares: (0..5)
                .map(|j| std::array::from_fn(|k| if k == j { 0.5 } else { 0.5 / 15.0 }))
                .collect(),
            far: (0..5)
                .map(|j| std::array::from_fn(|k| if k == j + 1 { 0.25 } else { 0.75 / 15.0 }))
                .collect(),
        },
        ..sample()
    }
}

#[test]
fn near_field_round_trips_and_is_optional() {
    let bf = with_near_field();
    let bytes = encode(&bf).unwrap();
    assert_eq!(parse(&bytes).unwrap(), bf);
    // Without it, the file has no NEAR section and reads back as none.
    let plain = encode(&sample()).unwrap();
    assert!(sections_of(&plain).iter().all(|s| &s.0 != b"NEAR"));
    assert!(parse(&plain).unwrap().near_field.is_empty());
    // A file from before far weights were stored (flags 0, shares only)
    // reads back without them, and its far weights are its shares.
    let mut old = bf.clone();
    old.near_field.far.clear();
    let read = parse(&encode(&old).unwrap()).unwrap();
    assert_eq!(read, old);
    assert_eq!(read.near_field.far_of(2), &old.near_field.shares[2]);
    assert_eq!(bf.near_field.far_of(2), &bf.near_field.far[2]);
    // In matrix order (the sample's permutation [2, 0, 1, 4, 3]):
    // receiver 0 is now row 1, and its neighbours 1 and 3 are 2 and 4.
    let order = [2u32, 0, 1, 4, 3];
    let new_of = [1u32, 2, 0, 4, 3];
    let r = bf.near_field.reordered(&order, &new_of);
    let links: Vec<u32> = r.links_of(1).iter().map(|l| l.patch).collect();
    assert_eq!(links, [2, 4]);
    assert_eq!(
        r.links_of(3)[0].patch,
        1,
        "file patch 4 is row 3, sees row 1"
    );
}

#[test]
fn near_field_errors_name_the_section_and_the_value() {
    let good = encode(&with_near_field()).unwrap();
    let at = |t: [u8; 4]| sections_of(&good).into_iter().find(|s| s.0 == t).unwrap().1;
    let near = at(*b"NEAR");
    // Rewrites NEAR's bytes and reseals the file.
    let with = |f: &dyn Fn(&mut Vec<u8>)| {
        let mut secs = sections_of(&good);
        for s in secs.iter_mut() {
            if &s.0 == b"NEAR" {
                f(&mut s.1);
            }
        }
        let refs: Vec<([u8; 4], &[u8])> = secs.iter().map(|(t, b)| (*t, b.as_slice())).collect();
        encode_sections(&refs)
    };
    let links_at = 16 + 4 * 6;
    type Edit = Box<dyn Fn(&mut Vec<u8>)>;
    let cases: Vec<(Edit, &str)> = vec![
        (
            Box::new(move |b: &mut Vec<u8>| {
                b[links_at..links_at + 4].copy_from_slice(&9u32.to_le_bytes())
            }),
            "neighbour 9 out of range",
        ),
        (
            Box::new(move |b: &mut Vec<u8>| {
                b[links_at..links_at + 4].copy_from_slice(&0u32.to_le_bytes())
            }),
            "neighbour 0 out of range or itself",
        ),
        (
            Box::new(|b: &mut Vec<u8>| b[0..4].copy_from_slice(&8u32.to_le_bytes())),
            "its links count 24 rays of 8",
        ),
        (
            Box::new(|b: &mut Vec<u8>| b.truncate(b.len() - 1)),
            "expected",
        ),
        (
            Box::new(move |b: &mut Vec<u8>| {
                let at = links_at + 3 * 36 + 64 + 4;
                b[at..at + 4].copy_from_slice(&f32::NAN.to_le_bytes())
            }),
            "patch 1: cell shares",
        ),
        (
            Box::new(move |b: &mut Vec<u8>| {
                let at = links_at + 3 * 36 + 5 * 64 + 3 * 64 + 8;
                b[at..at + 4].copy_from_slice(&(-0.5f32).to_le_bytes())
            }),
            "patch 3: far weights",
        ),
        (
            Box::new(|b: &mut Vec<u8>| b[12..16].copy_from_slice(&3u32.to_le_bytes())),
            "flags are 0x3",
        ),
        (
            // Flags say no far weights, but they are there.
            Box::new(|b: &mut Vec<u8>| b[12..16].copy_from_slice(&0u32.to_le_bytes())),
            "expected",
        ),
        (
            Box::new(|b: &mut Vec<u8>| b[8..12].copy_from_slice(&4u32.to_le_bytes())),
            "4 cells per link",
        ),
        (
            Box::new(|b: &mut Vec<u8>| b[16 + 8..16 + 12].copy_from_slice(&1u32.to_le_bytes())),
            "link starts decrease",
        ),
    ];
    assert_eq!(near.len(), 16 + 4 * 6 + 3 * 36 + 2 * 5 * 64);
    for (f, want) in cases {
        let (_, m) = reject(&with(&*f));
        assert!(m.contains("NEAR") && m.contains(want), "{want}: {m}");
    }
}

fn with_column_scales() -> BakeFile {
    let mut bf = sample();
    bf.codec.col_scale = vec![1.0, 0.5, 0.25, 1e-6, 0.75];
    bf
}

/// The matrix's column scales: written with flag bit 0 of the codec
/// descriptor and a CCOL section, read back exactly; a file without them
/// has neither; every inconsistency is an error naming the section.
#[test]
fn column_scales_round_trip_and_are_checked() {
    let bf = with_column_scales();
    let bytes = encode(&bf).unwrap();
    assert_eq!(parse(&bytes).unwrap(), bf);
    let secs = sections_of(&bytes);
    let cdsc = &secs.iter().find(|s| s.0 == tag::CODEC).unwrap().1;
    assert_eq!(u32::from_le_bytes(cdsc[12..16].try_into().unwrap()), 1);
    assert!(secs.iter().any(|s| s.0 == *b"CCOL"));
    let plain = encode(&sample()).unwrap();
    assert!(sections_of(&plain).iter().all(|s| s.0 != *b"CCOL"));
    assert!(parse(&plain).unwrap().codec.col_scale.is_empty());

    // Rewrites one section of the scaled file and reseals it.
    let with = |t: [u8; 4], f: &dyn Fn(&mut Vec<u8>)| {
        let mut secs = sections_of(&bytes);
        for s in secs.iter_mut().filter(|s| s.0 == t) {
            f(&mut s.1);
        }
        let refs: Vec<([u8; 4], &[u8])> = secs.iter().map(|(t, b)| (*t, b.as_slice())).collect();
        encode_sections(&refs)
    };
    let cases: Vec<(Vec<u8>, &str)> = vec![
        (
            with(*b"CCOL", &|b| set_f32(b, 4, 0.0)),
            "column 1's scale is 0",
        ),
        (
            with(*b"CCOL", &|b| set_f32(b, 8, f32::NAN)),
            "column 2's scale is NaN",
        ),
        (
            with(*b"CCOL", &|b| b.truncate(16)),
            "4 column scales for 5 patches",
        ),
        (
            with(tag::CODEC, &|b| set_u32(b, 12, 0)),
            "column scales present but the codec descriptor's flag bit 0 is not set",
        ),
    ];
    for (file, want) in cases {
        let (e, m) = reject(&file);
        assert!(matches!(e, BakeFileError::Invalid { .. }), "{m}");
        assert!(m.contains(want), "message {m:?} lacks {want:?}");
        assert!(m.contains("CCOL") || m.contains("CDSC"), "{m}");
    }
    // The writer refuses what the reader would reject.
    let mut bad = with_column_scales();
    bad.codec.col_scale[3] = -1.0;
    assert!(encode(&bad).is_err());
    bad.codec.col_scale.pop();
    assert!(encode(&bad).is_err());
}
