//! Fuzzes the `.rad` reader, `radiosity::bakefile::parse`, which must
//! return an error and never panic, whatever the bytes.
//!
//! Raw bytes alone rarely get past the magic and the checksums, so each
//! input is used three ways:
//! 1. as a whole file;
//! 2. as edits to a valid file (the input's bytes in threes: position high,
//!    position low, new value), with the file truncated to a length taken
//!    from the input when its first bit says so;
//! 3. the same edits followed by *resealing*: every checksum whose section
//!    lies inside the file, and the header checksum, recomputed. This
//!    reaches the table and field validation behind the checksums, where
//!    the interesting code is.
//!
//! A file that parses has its codec sections decoded too
//! (`codec::Encoded::from_blob`, which must also never panic, and whose
//! accepted matrices must gather without panicking).
//!
//! A file that parses must re-encode (the writer validates with the same
//! rules, so it must accept what the reader accepted) to bytes that parse
//! back to the same value. (Not necessarily to the same bytes: the reader
//! finds sections through the table, so a valid file may list them in
//! another order than the writer does.)

#![no_main]

use libfuzzer_sys::fuzz_target;
use radiosity::bake::encode::encode as encode_matrix;
use radiosity::bakefile::baked::Baked;
use radiosity::bakefile::codec::{CodecKind, Encoded};
use radiosity::bakefile::container::{header_checksum, ENTRY_LEN, HEADER_LEN};
use radiosity::bakefile::surface::{PatchSamples, SurfaceMap};
use radiosity::bakefile::records::{BakeInfo, BouncesRecord, OptionsRecord};
use radiosity::bakefile::{self, crc32, encode, parse, BakeFile, PatchRecord, SceneHash};
use std::sync::OnceLock;

/// A small valid bake file: 3 patches, 4 vertices.
fn base() -> &'static [u8] {
    static BASE: OnceLock<Vec<u8>> = OnceLock::new();
    BASE.get_or_init(|| {
        let bf = BakeFile {
            options_json: serde_json::to_string(&OptionsRecord {
                record_version: 1,
                target_patches: Some(3),
                voxel_size: 0.25,
                ff_samples: 4,
                ff_rays: 4,
                ff_quadrature_tol: 1e-3,
                bounces: BouncesRecord::INFINITE,
                reorder: "none".into(),
                codec: "bc1".into(),
                codec_choice: "fixed".into(),
                error_lights: 0,
                error_lights_seed: 1,
                ff_method: "rays".into(),
                ff_rays_per_patch: 64,
                two_sided: false,
                twinned: Vec::new(),
            })
            .unwrap(),
            scene_hash: SceneHash {
                obj: 1,
                obj_len: 2,
                mtl: 3,
                textures: 4,
            },
            patches: (0..3)
                .map(|i| PatchRecord {
                    centre: [i as f32, 0.0, 1.0],
                    normal: [0.0, 0.0, 1.0],
                    area: 1.0,
                    albedo: [0.5; 3],
                    emission: [0.0; 3],
                })
                .collect(),
            permutation: vec![1, 2, 0],
            near_field: Default::default(),
            // Sky visibility, so that the optional SKYV section's reader is
            // reached too.
            sky: radiosity::bakefile::sky::SkyVisibility::from_lists(
                64,
                &[vec![(3, 0.5), (40, 0.25)], vec![], vec![(255, 0.1)]],
            ),
            // Two probes, one with patch, sky and emission entries, so that
            // the optional PROB section's reader is reached too.
            probes: radiosity::bakefile::probes::Probes::from_entries(
                64,
                radiosity::bakefile::probes::ProbeGrid {
                    dims: [2, 1, 1],
                    origin: [0.0, 0.0, 0.5],
                    spacing: 1.0,
                },
                &[
                    radiosity::bakefile::probes::ProbeEntries {
                        state: None,
                        patches: vec![(0, [0.5, 0.0, 0.0, -0.9]), (2, [0.25, 0.6, 0.0, -0.6])],
                        sky: vec![(7, [1.0, 0.0, 0.9, 0.0])],
                        emission: vec![(0, [0.1, 0.0, 0.0, -0.5])],
                    },
                    radiosity::bakefile::probes::ProbeEntries {
                        state: Some(radiosity::bakefile::probes::ProbeState::Solid),
                        ..Default::default()
                    },
                ],
            ),
            // A real encoding (BC1 + log + an RGB9E5 sparse part), so that the
            // codec sections' own validation is reached too.
            codec: {
                let t: [Vec<f32>; 3] = std::array::from_fn(|c| {
                    (0..9).map(|k| ((k * 5 + c) % 7) as f32 * 0.01).collect()
                });
                let kind = CodecKind::parse("bc1:top=0.25,sparse=rgb9e5").unwrap();
                encode_matrix(kind, [&t[0], &t[1], &t[2]], 3)
                    .unwrap()
                    .to_blob()
            },
            surface_map: SurfaceMap::without_geometry(3),
            samples: PatchSamples::at_centres(
                &(0..3)
                    .map(|i| ([i as f32, 0.0, 1.0], [0.0, 0.0, 1.0]))
                    .collect::<Vec<_>>(),
            ),
            mesh_map: vec![
                [(0, 1.0), (0, 0.0), (0, 0.0), (0, 0.0)],
                [(1, 0.5), (2, 0.5), (0, 0.0), (0, 0.0)],
                [(0, 0.0); 4],
                [(2, 0.25), (1, 0.25), (0, 0.5), (0, 0.0)],
            ],
            info_json: serde_json::to_string(&BakeInfo {
                record_version: 1,
                generator: "fuzz".into(),
                scene: "scene.obj".into(),
                triangles: 0,
                vertices: 4,
                patches: 3,
                grey: false,
                spectral_bound: 0.5,
                h_error: None,
                mesh_map_fallbacks: 0,
                mesh_map_unmapped: 0,
            })
            .unwrap(),
        };
        encode(&bf).expect("the base file is valid")
    })
}

/// Recomputes every checksum that can be: the CRC of each table entry whose
/// section lies inside the file, then the header checksum.
fn reseal(b: &mut [u8]) {
    if b.len() < HEADER_LEN {
        return;
    }
    let count = u32::from_le_bytes([b[24], b[25], b[26], b[27]]) as usize;
    let Some(table_end) = count
        .checked_mul(ENTRY_LEN)
        .and_then(|t| t.checked_add(HEADER_LEN))
        .filter(|&t| t <= b.len())
    else {
        return;
    };
    for i in 0..count {
        let e = HEADER_LEN + ENTRY_LEN * i;
        let off = u64::from_le_bytes(b[e + 8..e + 16].try_into().unwrap());
        let len = u64::from_le_bytes(b[e + 16..e + 24].try_into().unwrap());
        if let Some(end) = off.checked_add(len).filter(|&end| end <= b.len() as u64) {
            let c = crc32(&b[off as usize..end as usize]);
            b[e + 4..e + 8].copy_from_slice(&c.to_le_bytes());
        }
    }
    let h = header_checksum(b, table_end);
    b[28..32].copy_from_slice(&h.to_le_bytes());
}

fuzz_target!(|data: &[u8]| {
    let _ = parse(data);

    let mut edited = base().to_vec();
    for e in data.get(1..).unwrap_or(&[]).chunks_exact(3) {
        let at = (e[0] as usize) << 8 | e[1] as usize;
        let len = edited.len();
        edited[at % len] = e[2];
    }
    if data.first().is_some_and(|f| f & 2 != 0) {
        let keep = data.get(1).map_or(0, |&k| k as usize * 2);
        edited.truncate(keep.min(edited.len()));
    }
    let _ = parse(&edited);
    reseal(&mut edited);
    if let Ok(bf) = parse(&edited) {
        let again = encode(&bf).expect("an accepted file re-encodes");
        assert_eq!(parse(&again).expect("a re-encoded file parses"), bf);
        // The codec sections: an error, or a matrix the run time can gather
        // from without panicking.
        if let Ok(e) = Encoded::from_blob(&bf.codec) {
            let b0 = vec![1.0f32; e.n];
            let _ = e.gather([&b0, &b0, &b0]);
        }
        // The whole load the run time does: records, codec, permutation.
        if let Ok(b) = Baked::from_file(&bf, "fuzz") {
            let h = vec![[1.0f32; 3]; b.patches.len()];
            let _ = b.interpolate_vertices(&h);
        }
    }
    let _ = bakefile::sections(&edited, "fuzz");
});
