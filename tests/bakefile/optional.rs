//! The optional sections: the near-field correction, the sky visibility and
//! the column scales, their round trips and their rejections.

use super::*;

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
                NearLink {
                    patch: 1,
                    counts,
                    from: [2; 16],
                },
                NearLink {
                    patch: 3,
                    counts: [1; 16],
                    from: [1; 16],
                },
                NearLink {
                    patch: 0,
                    counts,
                    from: [3; 16],
                },
            ],
            shares: (0..5)
                .map(|j| std::array::from_fn(|k| if k == j { 0.5 } else { 0.5 / 15.0 }))
                .collect(),
            far: (0..5)
                .map(|j| std::array::from_fn(|k| if k == j + 1 { 0.25 } else { 0.75 / 15.0 }))
                .collect(),
            sky: (0..5)
                .map(|j| std::array::from_fn(|k| (j * 16 + k) as f32 / 80.0))
                .collect(),
            cast: vec![[4; 16]; 5],
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
    // Nor before the cells' open sky was (flag bit 1): it reads back
    // without it, with or without far weights.
    for far in [true, false] {
        let mut old = bf.clone();
        old.near_field.sky.clear();
        old.near_field.cast.clear();
        for l in old.near_field.links.iter_mut() {
            l.from = [0; 16];
        }
        if !far {
            old.near_field.far.clear();
        }
        assert_eq!(parse(&encode(&old).unwrap()).unwrap(), old);
    }
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
            Box::new(move |b: &mut Vec<u8>| {
                let at = links_at + 3 * 36 + 2 * 5 * 64 + 4 * 64 + 12;
                b[at..at + 4].copy_from_slice(&1.5f32.to_le_bytes())
            }),
            "patch 4: open sky fractions",
        ),
        (
            // Link 0 counts 5 rays from receiver cell 0, which cast 4.
            Box::new(move |b: &mut Vec<u8>| {
                let at = links_at + 3 * 36 + 3 * 5 * 64;
                b[at..at + 2].copy_from_slice(&5u16.to_le_bytes())
            }),
            "counts 5 rays from cell 0, which cast 4",
        ),
        (
            Box::new(|b: &mut Vec<u8>| b[12..16].copy_from_slice(&15u32.to_le_bytes())),
            "flags are 0xf",
        ),
        (
            // Flags say no counts by the receiver's cell, but they are there.
            Box::new(|b: &mut Vec<u8>| b[12..16].copy_from_slice(&3u32.to_le_bytes())),
            "expected",
        ),
        (
            // Flags say no open sky fractions, but they are there.
            Box::new(|b: &mut Vec<u8>| b[12..16].copy_from_slice(&1u32.to_le_bytes())),
            "expected",
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
    assert_eq!(near.len(), 16 + 4 * 6 + 3 * 36 + 3 * 5 * 64 + (3 + 5) * 32);
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

/// The sample file with sky visibility: patch 2 open to the whole upper
/// hemisphere (π over four cells), the others partly, patch 0 not at all.
fn with_sky() -> BakeFile {
    let q = std::f32::consts::PI / 4.0;
    let lists: Vec<Vec<(u8, f32)>> = (0..5)
        .map(|i| match i {
            0 => vec![],
            2 => vec![(119, q), (120, q), (135, q), (136, q)],
            _ => vec![(10 * i as u8, q * i as f32 / 8.0), (200, 0.01)],
        })
        .collect();
    BakeFile {
        sky: radiosity::bakefile::sky::SkyVisibility::from_lists(256, &lists),
        ..sample()
    }
}

#[test]
fn sky_round_trips_and_is_optional() {
    let bf = with_sky();
    let bytes = encode(&bf).unwrap();
    assert_eq!(parse(&bytes).unwrap(), bf);
    // Without it, no SKYV section, and it reads back as none.
    let plain = encode(&sample()).unwrap();
    assert!(!plain.windows(4).any(|w| w == b"SKYV"));
    assert!(parse(&plain).unwrap().sky.is_empty());
    // A value out of range is refused naming the section and patch.
    let mut bad = with_sky();
    let k = bad.sky.starts[3] as usize;
    bad.sky.values[k] = 5.0;
    let e = encode(&bad).unwrap_err().to_string();
    assert!(e.contains("SKYV") && e.contains("patch 3"), "{e}");
}
