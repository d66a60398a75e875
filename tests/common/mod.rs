//! Helpers shared by the integration tests: small OBJ scenes written to a
//! fresh temporary directory, and the OpenCL device the tests must have.

#![allow(dead_code)]

pub mod open_box;

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

/// The faces of the axis-aligned box `[lo, hi]`, each one quad facing
/// outwards (a block), albedo `a`.
pub fn block(lo: [f64; 3], hi: [f64; 3], a: [f64; 3]) -> Vec<Quad> {
    let c: [f64; 3] = std::array::from_fn(|k| 0.5 * (lo[k] + hi[k]));
    let h: [f64; 3] = std::array::from_fn(|k| 0.5 * (hi[k] - lo[k]));
    let mut q = Vec::new();
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        for side in [-1.0, 1.0] {
            let mut cc = c;
            cc[axis] += side * h[axis];
            let mut eu = [0.0; 3];
            eu[u] = 1.0;
            let mut ev = [0.0; 3];
            // u × v is +axis; the face at −axis turns v round.
            ev[v] = side;
            q.push(quad(cc, eu, ev, h[u], h[v], a));
        }
    }
    q
}

/// The inward faces of the box `[lo, hi]`, each one quad, albedo `a` (a
/// block's faces turned round), in the order −x, +x, −y, +y, −z, +z: a
/// closed room, or with a face left out, a room open on that side.
pub fn box_inside(lo: [f64; 3], hi: [f64; 3], a: [f64; 3]) -> Vec<Quad> {
    block(lo, hi, a)
        .into_iter()
        .map(|mut q| {
            q.corners.reverse();
            q
        })
        .collect()
}

/// A 3 × 2 × 2 m room with a single-sided partition (x = 1.5, 1.2 m high,
/// facing −x) and a single-sided seat (a quad 0.45 m above the floor,
/// facing up), both seen from both sides and without back faces. With
/// `right`, every face of the room is wound towards it; without, the
/// ceiling and the +z wall face outwards: a user's model with faces wound
/// either way. The quads whose backs the room sees (without `right`):
/// ceiling, +z wall, partition, seat.
pub fn mixed_winding_room(right: bool) -> PathBuf {
    let mut quads: Vec<Quad> = block([0.0; 3], [3.0, 2.0, 2.0], [0.7; 3])
        .into_iter()
        .enumerate()
        .map(|(k, mut q)| {
            // block's order: −x, +x, −y, +y (ceiling), −z, +z.
            if right || (k != 3 && k != 5) {
                q.corners.reverse();
            }
            q
        })
        .collect();
    let partition = quad(
        [1.5, 0.6, 1.0],
        [0.0, 0.0, 1.0],
        [0.0, 1.0, 0.0],
        1.0,
        0.6,
        [0.6, 0.7, 0.8],
    );
    let seat = quad(
        [2.4, 0.45, 1.0],
        [0.0, 0.0, 1.0],
        [1.0, 0.0, 0.0],
        0.2,
        0.2,
        [0.8, 0.5, 0.3],
    );
    quads.extend([partition, seat]);
    write_quads(
        if right {
            "winding-right"
        } else {
            "winding-mixed"
        },
        &quads,
    )
}

/// A 1 m square floor at y = 0 facing up, centred on the origin.
pub fn unit_floor() -> Quad {
    quad(
        [0.0, 0.0, 0.0],
        [0.0, 0.0, 1.0],
        [1.0, 0.0, 0.0],
        0.5,
        0.5,
        [0.5; 3],
    )
}

/// [`unit_floor`] under a ceiling of the same size at y = 0.5 facing down:
/// the scene of the tests of a light in a surface's plane, written as an
/// OBJ.
pub fn floor_under_ceiling(tag: &str) -> PathBuf {
    let ceiling = quad(
        [0.0, 0.5, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0],
        0.5,
        0.5,
        [0.5; 3],
    );
    write_quads(tag, &[unit_floor(), ceiling])
}

/// The mean x of the vertices of the triangles of material `name` in the
/// scene at `obj` (a wall's plane in the Cornell box).
pub fn wall_x(obj: &Path, name: &str) -> f64 {
    let s = radiosity::core::scene::load(obj).unwrap();
    let m = s.materials.iter().position(|m| m.name == name).unwrap() as u32;
    let xs: Vec<f64> = s
        .triangles
        .iter()
        .zip(&s.triangle_material)
        .filter(|(_, &tm)| tm == m)
        .flat_map(|(t, _)| t.iter().map(|&v| f64::from(s.positions[v as usize][0])))
        .collect();
    xs.iter().sum::<f64>() / xs.len() as f64
}
