//! Fuzzes the glTF loader, `radiosity::core::scene::load` on a `.glb` and
//! a `.gltf`, which must return a scene or an error and never panic,
//! whatever the bytes. The same bytes are tried both ways: as a binary
//! file (the GLB container's chunk checks) and as JSON text (the document's
//! validation, the accessors' bounds). `tests/gltf/bad.rs` runs seeded
//! mutations of valid files in the test suite; this target explores past
//! them (`cargo fuzz run gltf_loader`).

#![no_main]

use libfuzzer_sys::fuzz_target;
use std::sync::atomic::{AtomicUsize, Ordering};

fuzz_target!(|data: &[u8]| {
    static N: AtomicUsize = AtomicUsize::new(0);
    let dir = std::env::temp_dir().join(format!(
        "radiosity-fuzz-gltf-{}-{}",
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed) % 4
    ));
    let _ = std::fs::create_dir_all(&dir);
    for name in ["f.glb", "f.gltf"] {
        let path = dir.join(name);
        if std::fs::write(&path, data).is_ok() {
            if let Ok(scene) = radiosity::core::scene::load(&path) {
                // A loaded scene is a valid one: its summary prints.
                let _ = scene.summary().to_string();
            }
        }
    }
});
