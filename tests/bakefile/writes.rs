//! Atomic writes (a failed write leaves the old file; readers never see a
//! partial one) and the scene hash that ties a bake to its OBJ and MTL.

use super::*;

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
