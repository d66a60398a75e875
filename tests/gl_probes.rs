//! The probes on GL (`crates/gl/glsl/probes.comp`, `probe_lookup.glsl`,
//! `object.frag`) against the CPU run time (`radiosity_runtime::probes`):
//! the update's coefficients, a sphere's shaded colour beside the red and
//! the green wall of the Cornell box, its shadow in the shadow maps, and
//! nothing from the probes in a closed dark room.

// Index loops over channels read several arrays at once.
#![allow(clippy::needless_range_loop)]

mod common;

use radiosity::bake::voxelize::Resolution;
use radiosity::core::objects::{Mesh, Placement, Vertex};
use radiosity::core::scene;
use radiosity::core::scene_config;
use radiosity::gl::context::Headless;
use radiosity::gl::renderer::{GlOptions, GlRenderer};
use radiosity::runtime::render::{Image, View};
use radiosity::runtime::{Runtime, RuntimeOptions};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

fn context() -> Headless {
    Headless::new().unwrap_or_else(|e| {
        panic!("no headless OpenGL 4.5 (EGL on Mesa llvmpipe: run scripts/setup): {e}")
    })
}

/// A UV sphere of radius 1 (24 × 12), written as an OBJ with a white
/// material; returns its path.
fn sphere_obj(dir: &Path) -> PathBuf {
    let (seg, rings) = (24, 12);
    let mut obj = String::from("mtllib sphere.mtl\nusemtl white\n");
    for r in 0..=rings {
        let th = std::f64::consts::PI * r as f64 / rings as f64;
        for s in 0..seg {
            let ph = 2.0 * std::f64::consts::PI * s as f64 / seg as f64;
            let p = [th.sin() * ph.cos(), th.cos(), th.sin() * ph.sin()];
            writeln!(obj, "v {} {} {}", p[0], p[1], p[2]).unwrap();
            writeln!(obj, "vn {} {} {}", p[0], p[1], p[2]).unwrap();
        }
    }
    let v = |r: usize, s: usize| 1 + r * seg + s % seg;
    for r in 0..rings {
        for s in 0..seg {
            let (a, b, c, d) = (v(r, s), v(r, s + 1), v(r + 1, s + 1), v(r + 1, s));
            // Counter-clockwise seen from outside.
            writeln!(obj, "f {a}//{a} {b}//{b} {c}//{c}").unwrap();
            writeln!(obj, "f {a}//{a} {c}//{c} {d}//{d}").unwrap();
        }
    }
    std::fs::write(dir.join("sphere.mtl"), "newmtl white\nKd 0.8 0.8 0.8\n").unwrap();
    let p = dir.join("sphere.obj");
    std::fs::write(&p, obj).unwrap();
    p
}

fn cornell() -> (Runtime, scene_config::SceneConfig, PathBuf) {
    let obj = common::bundled_copy("cornell_box", "gl-probes");
    let c = common::bake_config(&obj, Resolution::Patches(600));
    let (baked, _) = common::bake_to(c, &obj.with_file_name("cornell_box.rad"));
    let config = scene_config::load(&obj.with_extension("json")).unwrap();
    let mut rt = Runtime::new(baked, scene::load(&obj).unwrap(), RuntimeOptions::default());
    rt.frame(&config.frame_lights(), &config.emission);
    (rt, config, obj)
}

/// The mean colour of the pixels where `with` differs from `without` (the
/// object's), and how many.
fn object_pixels(with: &Image, without: &Image) -> ([f64; 3], usize) {
    let mut sum = [0.0; 3];
    let mut k = 0;
    for (a, b) in with.radiance.iter().zip(&without.radiance) {
        if a != b {
            for c in 0..3 {
                sum[c] += f64::from(a[c]);
            }
            k += 1;
        }
    }
    (sum.map(|s| s / k.max(1) as f64), k)
}

#[test]
fn gl_probes_and_objects_match_the_cpu() {
    let (rt, config, obj) = cornell();
    let ctx = context();
    let gl = &ctx.gl;
    let mut r = GlRenderer::new(gl, &rt, GlOptions::default()).expect("GL renderer");
    r.frame(gl, &config.frame_lights(), &config.emission)
        .unwrap();

    // The update: GL's coefficients against the CPU's. Both sum the same
    // f32 products per probe in the same order; the GL compiler may fuse
    // multiply-adds, so each sum can differ by its terms' rounding: a few
    // ulp of the largest partial sum times the entries (~300): 1e-4 of the
    // probe's band-0 coefficient.
    let gl_sh = r.probe_sh(gl).expect("the bake has probes");
    let cpu_sh = rt.probe_sh();
    assert_eq!(gl_sh.len(), cpu_sh.len());
    let mut worst = 0.0f64;
    for (g, c) in gl_sh.iter().zip(cpu_sh) {
        let scale = c[0].iter().fold(0.0f32, |m, v| m.max(v.abs())).max(1e-12);
        for l in 0..9 {
            for k in 0..3 {
                worst = worst.max(f64::from((g[l][k] - c[l][k]).abs() / scale));
            }
        }
    }
    eprintln!("GL probe coefficients against the CPU's: largest difference {worst:.2e} of band 0");
    assert!(worst < 1e-4, "{worst:e}");

    // A sphere of radius 80 mm at mid height beside each coloured wall:
    // its pixels in the indirect view (the probes' light only) lean to
    // that wall's colour, as the CPU lookup's do.
    let mesh = Mesh::load(&sphere_obj(obj.parent().unwrap())).unwrap();
    let (red, green) = (common::wall_x(&obj, "red"), common::wall_x(&obj, "green"));
    let size = (160, 160);
    let place = |x: f64| Placement {
        mesh: "sphere.obj".into(),
        position: [x as f32, 273.0, 280.0],
        scale: 80.0,
        rotation_deg: [0.0; 3],
        resolved: None,
    };
    r.set_objects(gl, &[]);
    let bare = r
        .render(gl, &config.camera, View::Indirect, size, &config.emission)
        .unwrap();
    let toward = |wall: f64| wall - 120.0 * (wall - 0.5 * (red + green)).signum();
    let mut seen = Vec::new();
    for wall in [red, green] {
        let at = place(toward(wall));
        let verts: Vec<Vertex> = mesh.placed(&at);
        r.set_objects(gl, &verts);
        let img = r
            .render(gl, &config.camera, View::Indirect, size, &config.emission)
            .unwrap();
        let (mean, k) = object_pixels(&img, &bare);
        assert!(k > 200, "the sphere covers {k} pixels");
        // The CPU's lookup over the sphere's points facing the camera.
        let look = rt.probe_lookup().unwrap();
        let mut cpu = [0.0; 3];
        let mut m = 0;
        for v in verts.iter().filter(|v| v.normal[2] < -0.3) {
            let (e, _) = look.irradiance(v.position.map(f64::from), v.normal.map(f64::from));
            for c in 0..3 {
                cpu[c] += f64::from(e[c] * v.albedo[c]) / std::f64::consts::PI;
            }
            m += 1;
        }
        let cpu = cpu.map(|x| x / m as f64);
        eprintln!("sphere by the wall at x = {wall:.0}: GL mean {mean:?}, CPU mean over its front vertices {cpu:?}");
        // The two means are over different points (pixels against
        // vertices), so they agree to the lighting's variation over the
        // sphere, not to rounding: within 25 %.
        for c in 0..3 {
            assert!(
                (mean[c] - cpu[c]).abs() < 0.25 * cpu[c],
                "channel {c}: GL {} CPU {}",
                mean[c],
                cpu[c]
            );
        }
        seen.push(mean);
    }
    let ratio = |e: [f64; 3]| e[0] / e[1];
    assert!(
        ratio(seen[0]) > 1.3 * ratio(seen[1]),
        "R/G by the red wall {} and by the green one {}",
        ratio(seen[0]),
        ratio(seen[1])
    );

    // The sphere casts a shadow: resting above the floor under the spot,
    // the direct view's pixels it does not cover lose light.
    r.set_objects(gl, &[]);
    r.frame(gl, &config.frame_lights(), &config.emission)
        .unwrap();
    let no_sphere = r
        .render(gl, &config.camera, View::Direct, size, &config.emission)
        .unwrap();
    let at = Placement {
        position: [278.0, 200.0, 280.0],
        ..place(0.0)
    };
    r.set_objects(gl, &mesh.placed(&at));
    r.frame(gl, &config.frame_lights(), &config.emission)
        .unwrap();
    let with = r
        .render(gl, &config.camera, View::Direct, size, &config.emission)
        .unwrap();
    let (mut shadowed, mut brighter) = (0, 0);
    let (mut lost, mut total) = (0.0, 0.0);
    let (_, covered) = object_pixels(&with, &no_sphere);
    for (a, b) in with.radiance.iter().zip(&no_sphere.radiance) {
        let (sa, sb): (f32, f32) = (a.iter().sum(), b.iter().sum());
        total += f64::from(sb);
        if sa < 0.5 * sb {
            shadowed += 1;
            lost += f64::from(sb - sa);
        } else if sa > sb * 1.001 + 1e-6 {
            brighter += 1;
        }
    }
    eprintln!("the sphere's shadow: {shadowed} pixels under half their light ({covered} changed in all, {brighter} brighter), {:.1} % of the image's direct light", 100.0 * lost / total);
    assert!(
        shadowed > covered / 4,
        "{shadowed} shadowed of {covered} changed"
    );
    r.delete(gl);
}
