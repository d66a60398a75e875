//! Helpers shared by the integration tests: small OBJ scenes written to a
//! fresh temporary directory, and the OpenCL device the tests must have.

#![allow(dead_code)]

use radiosity::bake::voxelize::Resolution;
use radiosity::bake::{self, BakeConfig, BakeOutput, CodecChoice, ComputeChoice};
use radiosity::bakefile::baked::Baked;
use radiosity::bakefile::codec::CodecKind;
use radiosity::core::compute::{DeviceSelection, Gpu};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

/// A fresh, empty directory under the system temp dir, unique per call.
pub fn temp_dir(tag: &str) -> PathBuf {
    static N: AtomicUsize = AtomicUsize::new(0);
    let dir = std::env::temp_dir().join(format!(
        "radiosity-test-{}-{}-{}",
        tag,
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed)
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("creating a temp dir");
    dir
}

/// A planar quad (corners in counter-clockwise order seen from its front)
/// with a material albedo.
#[derive(Clone, Copy)]
pub struct Quad {
    pub corners: [[f64; 3]; 4],
    pub albedo: [f64; 3],
}

/// Writes quads as an OBJ + MTL (one material per distinct albedo) and
/// returns the OBJ's path. Coordinates are printed with `{:?}` so they
/// round-trip exactly through f32 parsing when they are exact in f32.
pub fn write_quads(tag: &str, quads: &[Quad]) -> PathBuf {
    let dir = temp_dir(tag);
    let mut obj = String::from("mtllib scene.mtl\n");
    let mut mtl = String::new();
    for (i, q) in quads.iter().enumerate() {
        writeln!(
            mtl,
            "newmtl m{i}\nKd {} {} {}\n",
            q.albedo[0], q.albedo[1], q.albedo[2]
        )
        .unwrap();
        for c in &q.corners {
            writeln!(
                obj,
                "v {:?} {:?} {:?}",
                c[0] as f32, c[1] as f32, c[2] as f32
            )
            .unwrap();
        }
        let b = 4 * i + 1;
        writeln!(obj, "usemtl m{i}\nf {} {} {} {}", b, b + 1, b + 2, b + 3).unwrap();
    }
    std::fs::write(dir.join("scene.mtl"), mtl).unwrap();
    let path = dir.join("scene.obj");
    std::fs::write(&path, obj).unwrap();
    path
}

/// An axis-free quad: centre `c`, unit normal `n`, in-plane unit axes `u`,
/// `v` (with u × v = n), half sizes `hu`, `hv`.
pub fn quad(c: [f64; 3], u: [f64; 3], v: [f64; 3], hu: f64, hv: f64, albedo: [f64; 3]) -> Quad {
    let p = |su: f64, sv: f64| -> [f64; 3] {
        std::array::from_fn(|k| c[k] + su * hu * u[k] + sv * hv * v[k])
    };
    Quad {
        corners: [p(-1.0, -1.0), p(1.0, -1.0), p(1.0, 1.0), p(-1.0, 1.0)],
        albedo,
    }
}

/// The OpenCL device every OpenCL test runs on. Fails (never skips) with
/// a message saying how to get one.
pub fn gpu() -> Gpu {
    let sel = DeviceSelection::from_flag_or_env(None).expect("RADIOSITY_CL_DEVICE is malformed");
    Gpu::new(sel).unwrap_or_else(|e| {
        panic!(
            "this test needs an OpenCL device and found none: {e}\n\
             run scripts/setup (installs PoCL, the CPU OpenCL driver)"
        )
    })
}

/// `../shared/scenes/sponza/sponza.obj` relative to the crate; fails with a
/// clear message when it is missing.
pub fn sponza() -> PathBuf {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes/sponza/sponza.obj");
    assert!(
        p.exists(),
        "the Sponza scene is missing at {}: the tests need ../shared beside the checkout",
        p.display()
    );
    p
}

/// A bundled scene's OBJ path.
pub fn bundled(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(format!("scenes/{name}/{name}.obj"))
}

/// The bundled scene `name` (its OBJ, MTL and camera/lights file) copied
/// into a fresh temporary directory tagged `tag`, for tests that bake
/// beside it or edit it; returns the copied OBJ's path.
pub fn bundled_copy(name: &str, tag: &str) -> PathBuf {
    let src = bundled(name);
    let dir = temp_dir(tag);
    for ext in ["obj", "mtl", "json"] {
        let f = format!("{name}.{ext}");
        std::fs::copy(src.with_file_name(&f), dir.join(&f))
            .unwrap_or_else(|e| panic!("copying {f}: {e}"));
    }
    dir.join(format!("{name}.obj"))
}

/// The tests' bake options for `obj`: the OpenCL device, the default codec
/// fixed (no search), no compression-error lights.
pub fn bake_config(obj: &Path, resolution: Resolution) -> BakeConfig {
    let mut c = BakeConfig::new(obj.to_path_buf(), resolution);
    c.compute = ComputeChoice::OpenCl(Default::default());
    c.codec = CodecChoice::Fixed(CodecKind::default());
    c.error_lights = 0;
    c
}

/// Bakes `config` to `out` and loads the file back.
pub fn bake_to(mut config: BakeConfig, out: &Path) -> (Baked, BakeOutput) {
    config.output = Some(out.to_path_buf());
    gpu();
    let report = bake::run(&config, &mut |_| {}).expect("bake");
    (Baked::load(out).unwrap(), report)
}

/// The exposure `radiosity render` (or the headless view) printed on
/// stderr ("…; exposure K").
pub fn printed_exposure(stderr: &str) -> String {
    stderr
        .rsplit("exposure ")
        .next()
        .and_then(|t| t.split_whitespace().next())
        .unwrap_or_else(|| panic!("no exposure printed: {stderr}"))
        .to_string()
}
