//! The reader's rejections of section contents whose checksums are
//! valid (what a buggy writer would produce), each message naming the
//! section, the record and the value; the writer refuses the same.

use super::*;

// ---------------------------------------------------------------------------
// Content rejections (checksums valid: what a buggy writer would produce)

fn reject_section(t: [u8; 4], f: impl FnOnce(&mut Vec<u8>), expect: &[&str]) {
    let (e, m) = reject(&with_section(t, f));
    assert!(matches!(e, BakeFileError::Invalid { .. }), "{m}");
    for want in expect {
        assert!(m.contains(want), "message {m:?} lacks {want:?}");
    }
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
