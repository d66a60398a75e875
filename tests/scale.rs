//! Units: the same scene modelled in millimetres, metres and kilometres
//! (every coordinate times 10⁻³, 2⁻¹⁰, 1 or 10³, the voxel size with it)
//! must bake to the same patches and light the same under the same sun. Form
//! factors, albedo and a directional light's irradiance have no unit, so
//! `H` and the rendered radiance are the same numbers at every scale; any
//! offset, tolerance or epsilon in absolute units would show here.

mod common;

use common::{quad, write_quads, Quad};
use radiosity::bake::voxelize::Resolution;
use radiosity::core::scene;
use radiosity::core::scene_config::{Camera, Light, SceneConfig};
use radiosity::runtime::render::{render, View};
use radiosity::runtime::texture::Albedo;
use radiosity::runtime::{Runtime, RuntimeOptions};
use std::collections::BTreeMap;

/// A yard 4 × 4 with walls 2 high on three sides (open above and on the
/// fourth side) and a block 1 × 1.2 × 0.8 standing in it, in units of `s`.
/// Big untessellated quads: one per face.
fn yard(s: f64) -> Vec<Quad> {
    let q = |c: [f64; 3], u: [f64; 3], v: [f64; 3], hu: f64, hv: f64, a: [f64; 3]| {
        quad(c.map(|x| x * s), u, v, hu * s, hv * s, a)
    };
    let (floor, wall, block) = ([0.6, 0.55, 0.5], [0.7, 0.3, 0.3], [0.3, 0.6, 0.4]);
    vec![
        q(
            [2.0, 0.0, 2.0],
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 0.0],
            2.0,
            2.0,
            floor,
        ),
        // Walls at x = 0 (facing +x), z = 0 (facing +z), z = 4 (facing −z).
        q(
            [0.0, 1.0, 2.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            1.0,
            2.0,
            wall,
        ),
        q(
            [2.0, 1.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            2.0,
            1.0,
            wall,
        ),
        q(
            [2.0, 1.0, 4.0],
            [0.0, 1.0, 0.0],
            [1.0, 0.0, 0.0],
            1.0,
            2.0,
            wall,
        ),
        // The block over x in [1.7, 2.7], z in [1.1, 1.9], 1.2 high.
        q(
            [2.2, 1.2, 1.5],
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 0.0],
            0.4,
            0.5,
            block,
        ),
        q(
            [2.7, 0.6, 1.5],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            0.6,
            0.4,
            block,
        ),
        q(
            [1.7, 0.6, 1.5],
            [0.0, 0.0, 1.0],
            [0.0, 1.0, 0.0],
            0.4,
            0.6,
            block,
        ),
        q(
            [2.2, 0.6, 1.9],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            0.5,
            0.6,
            block,
        ),
        q(
            [2.2, 0.6, 1.1],
            [0.0, 1.0, 0.0],
            [1.0, 0.0, 0.0],
            0.6,
            0.5,
            block,
        ),
    ]
}

struct Lit {
    /// Per patch: the centre in units of the scale, and `H`.
    patches: Vec<([f64; 3], [f64; 3])>,
    /// The final view's radiance, row-major.
    image: Vec<[f32; 3]>,
}

fn bake_and_light(s: f64, tag: &str) -> Lit {
    let obj = write_quads(tag, &yard(s));
    let c = common::bake_config(&obj, Resolution::VoxelSize(0.25 * s));
    let (baked, _) = common::bake_to(c, &obj.with_extension("rad"));
    let mut rt = Runtime::new(baked, scene::load(&obj).unwrap(), RuntimeOptions::default());
    let sun = Light::Directional {
        direction: [-0.4, -1.0, 0.3],
        irradiance: [10.0, 9.0, 8.0],
    };
    rt.frame(std::slice::from_ref(&sun), &BTreeMap::new());
    let mut patches: Vec<([f64; 3], [f64; 3])> = rt
        .baked
        .patches
        .iter()
        .enumerate()
        .map(|(j, p)| {
            (
                p.centre.map(|x| x as f64 / s),
                std::array::from_fn(|ch| rt.h()[ch][j] as f64),
            )
        })
        .collect();
    // By centre, rounded to 1e-4 units (centres lie on a 1/8-unit lattice
    // of the voxel grid; the scales differ in the 7th digit).
    patches.sort_by_key(|p| p.0.map(|x| (x * 1e4).round() as i64));
    let config = SceneConfig {
        objects: Vec::new(),
        sky: None,
        emission: BTreeMap::new(),
        camera: Camera {
            position: [(3.9 * s) as f32, (1.6 * s) as f32, (3.6 * s) as f32],
            target: [(1.0 * s) as f32, (0.3 * s) as f32, (1.0 * s) as f32],
            up: [0.0, 1.0, 0.0],
            fov_y_deg: 60.0,
        },
        lights: vec![sun],
        units: "m".into(),
        description: String::new(),
    };
    let albedo = Albedo::new(&rt.scene);
    let (img, stats) = render(&rt, &config, View::Final, 96, 72, &albedo);
    assert!(stats.hits > 0, "the camera sees the yard at scale {s}");
    Lit {
        patches,
        image: img.radiance,
    }
}

#[test]
fn the_same_scene_in_millimetres_metres_and_kilometres_lights_the_same() {
    let metres = bake_and_light(1.0, "scale-m");
    let total: f64 = metres.patches.iter().map(|p| p.1.iter().sum::<f64>()).sum();
    assert!(total > 0.0, "the sun gives indirect light");
    // (scale, tag, bound on H's relative RMS and on the image's, bound on
    // the relative difference of the area-weighted total of H.)
    //
    // * 1/1024 ("millimetres" in a power of two): every coordinate and the
    //   voxel size scale exactly, so the bake is the same to the bit
    //   (measured 0).
    // * 1000 (kilometres): the voxel size 250 is exact, but coordinates
    //   like 1.7 × 1000 round differently in f32 than 1.7 (1e-7 relative);
    //   measured 6e-5 for H, 1.5e-5 for the image. 1e-3 allows dozens of
    //   ray or shadow decisions to flip on that rounding, while an
    //   absolute-unit epsilon anywhere (1e-4 scene units is 0.1 m in
    //   kilometres, 100 voxels in millimetres) moves whole surfaces.
    // * 1e-3 (millimetres): the voxel size 0.00025 is not exact in binary,
    //   so the wall at z = 0.004 and the edges at 0.002 and 0.004 lie a
    //   rounding away from the voxel boundaries that hold them exactly at
    //   the other scales: another, equally valid voxelization. H moves as
    //   from one patching to the next (measured 1.1 % RMS, image 0.2 %);
    //   the total stays (measured 1e-4; a unit error would move it by
    //   orders of magnitude).
    let cases = [
        (1.0 / 1024.0, "scale-p2", 1e-6, 1e-6),
        (1e3, "scale-km", 1e-3, 1e-4),
        (1e-3, "scale-mm", 3e-2, 1e-3),
    ];
    for (s, tag, bound, total_bound) in cases {
        let other = bake_and_light(s, tag);
        assert_eq!(
            other.patches.len(),
            metres.patches.len(),
            "patches at scale {s}"
        );
        // The same patches, by centre in scaled units.
        let (mut d2, mut r2) = (0.0f64, 0.0f64);
        for (a, b) in other.patches.iter().zip(&metres.patches) {
            let off = (0..3).map(|k| (a.0[k] - b.0[k]).abs()).fold(0.0, f64::max);
            assert!(
                off < 1e-4,
                "scale {s}: patch at {:?} against {:?}",
                a.0,
                b.0
            );
            for ch in 0..3 {
                d2 += (a.1[ch] - b.1[ch]).powi(2);
                r2 += b.1[ch].powi(2);
            }
        }
        let e_h = (d2 / r2).sqrt();
        let (mut d2, mut r2) = (0.0f64, 0.0f64);
        for (a, b) in other.image.iter().zip(&metres.image) {
            for ch in 0..3 {
                d2 += (a[ch] as f64 - b[ch] as f64).powi(2);
                r2 += (b[ch] as f64).powi(2);
            }
        }
        let e_img = (d2 / r2).sqrt();
        let t: f64 = other.patches.iter().map(|p| p.1.iter().sum::<f64>()).sum();
        let e_total = (t / total - 1.0).abs();
        eprintln!("scale {s}: H relative RMS {e_h:.2e}, image {e_img:.2e}, total {e_total:.2e}");
        assert!(e_h <= bound, "scale {s}: H differs by {e_h} (relative RMS)");
        assert!(e_img <= bound, "scale {s}: the image differs by {e_img}");
        assert!(
            e_total <= total_bound,
            "scale {s}: total H differs by {e_total}"
        );
    }
}
