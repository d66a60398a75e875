//! Direct light on patches against closed forms: inverse-square point
//! lights, cosine-weighted directional light, spot profiles, and shadows.

mod common;

use common::{quad, write_quads};
use radiosity::bake::voxelize::voxelize_at;
use radiosity::core::compute::Backend;
use radiosity::core::direct::{exitance, random_lights, DirectLight, ShadowCache};
use radiosity::core::light::{incident, incident_prepared, Prepared};
use radiosity::core::math::{cross, dot, normalize, SplitMix64};
use radiosity::core::scene;
use radiosity::core::scene_config::Light;

/// A 1 × 1 floor at y = 0 (facing up), voxel size 0.25 (16 patches), and
/// optionally a 0.5 × 1 roof at y = 0.5 over its x < 0 half (facing down).
fn floor(with_roof: bool) -> (scene::Scene, Vec<radiosity::core::patch::Patch>) {
    let mut quads = vec![common::unit_floor()];
    if with_roof {
        quads.push(quad(
            [-0.25, 0.5, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0],
            0.25,
            0.5,
            [0.5; 3],
        ));
    }
    let s = scene::load(&write_quads("direct", &quads)).unwrap();
    let v = voxelize_at(&s, 0.25, &Backend::Cpu).unwrap();
    let patches = v
        .patches
        .into_iter()
        .filter(|p| p.normal[1] > 0.99)
        .collect();
    (s, patches)
}

#[test]
fn point_light_follows_the_inverse_square_law() {
    let (s, patches) = floor(false);
    assert_eq!(patches.len(), 16);
    let light = Light::Point {
        position: [0.0, 2.0, 0.0],
        intensity: [4.0, 2.0, 1.0],
    };
    let d = DirectLight::new(&s).irradiance(&patches, &[light]);
    for (p, d) in patches.iter().zip(&d) {
        // The mean over the patch's four sample points of I cos / r² with
        // cos = h / r: computed here in closed form at the same points.
        let h = 0.25 * p.area.sqrt();
        let mut e = 0.0;
        for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)] {
            let (x, z) = (p.centre[0] + h * a, p.centre[2] + h * b);
            let r2: f64 = x * x + z * z + 4.0;
            e += 2.0 / r2.powf(1.5) / 4.0;
        }
        // Only the ray offset (1e-4 of the extent) separates the two.
        for (c, i) in [4.0, 2.0, 1.0].iter().enumerate() {
            assert!(
                (d[c] - i * e).abs() <= 1e-3 * i * e,
                "{} vs {}",
                d[c],
                i * e
            );
        }
    }
}

#[test]
fn directional_light_is_cosine_weighted_and_shadowed() {
    let (s, patches) = floor(true);
    // Straight down: the roof (x < 0) shadows exactly the floor's x < 0 half.
    let light = Light::Directional {
        direction: [0.0, -1.0, 0.0],
        irradiance: [2.0; 3],
    };
    let dl = DirectLight::new(&s);
    let d = dl.irradiance(&patches, &[light]);
    for (p, d) in patches.iter().zip(&d) {
        let expected = if p.centre[0] < 0.0 { 0.0 } else { 2.0 };
        assert_eq!(d[0], expected, "patch at x = {}", p.centre[0]);
    }
    // At 60° from the vertical, cos = 0.5 on the unshadowed far side.
    let t = 60f32.to_radians();
    let light = Light::Directional {
        direction: [-t.sin(), -t.cos(), 0.0],
        irradiance: [2.0; 3],
    };
    let d = dl.irradiance(&patches, &[light]);
    let max = d.iter().map(|d| d[0]).fold(0.0, f64::max);
    assert!((max - 1.0).abs() < 1e-6, "{max}");
}

#[test]
fn spot_profile_and_exitance() {
    let (s, patches) = floor(false);
    // A narrow spot straight down at the floor's centre lights only the four
    // central patches' inner sample points.
    let light = Light::Spot {
        position: [0.0, 1.0, 0.0],
        direction: [0.0, -1.0, 0.0],
        intensity: [1.0; 3],
        cone_angle_deg: 10.0,
        beam_angle_deg: 5.0,
    };
    let d = DirectLight::new(&s).irradiance(&patches, &[light]);
    let lit = d.iter().filter(|d| d[0] > 0.0).count();
    assert_eq!(lit, 4);
    let b0 = exitance(&patches, &d);
    for ((p, d), b) in patches.iter().zip(&d).zip(&b0) {
        assert_eq!(b[1], p.albedo[1] * d[1] + p.emission[1]);
    }
}

/// A spot's profile skips the `acos` where the cosine of the angle to its
/// axis is surely outside the cone or inside the beam: the same bits as
/// the definition (the same prepared spot with the shortcut disabled), on
/// points spread over the whole sphere around spots of every cone and
/// beam, half of them within 1e-6° of a boundary.
#[test]
fn a_spots_shortcuts_change_no_bit_of_its_light() {
    let mut rng = SplitMix64::new(3);
    let mut shortcut = [0usize; 3];
    for case in 0..400 {
        let cone = if case % 7 == 0 {
            179.9
        } else {
            0.1 + 170.0 * rng.uniform()
        };
        let beam = match case % 3 {
            0 => 0.0,
            1 => cone,
            _ => cone * rng.uniform(),
        };
        let dir = [
            rng.uniform() - 0.5,
            rng.uniform() - 0.5,
            rng.uniform() - 0.5,
        ];
        let light = Light::Spot {
            position: [1.0, 2.0, 3.0],
            direction: dir.map(|v| v as f32),
            intensity: [1.0, 2.0, 3.0],
            cone_angle_deg: cone as f32,
            beam_angle_deg: beam as f32,
        };
        let fast = Prepared::new(&light);
        let Prepared::Spot {
            position,
            axis,
            cos_outside,
            cos_inside,
            ..
        } = fast
        else {
            unreachable!()
        };
        let mut plain = fast;
        if let Prepared::Spot {
            cos_outside,
            cos_inside,
            ..
        } = &mut plain
        {
            *cos_outside = f64::NEG_INFINITY;
            *cos_inside = f64::INFINITY;
        }
        // An orthonormal frame around the axis.
        let t = if axis[0].abs() < 0.9 {
            [1.0, 0.0, 0.0]
        } else {
            [0.0, 1.0, 0.0]
        };
        let u = normalize(cross(axis, t));
        let v = cross(axis, u);
        for k in 0..200 {
            let theta = match k % 4 {
                0 => (cone as f32 as f64) + 1e-6 * (rng.uniform() - 0.5),
                1 => (beam as f32 as f64) + 1e-6 * (rng.uniform() - 0.5),
                _ => 180.0 * rng.uniform(),
            }
            .to_radians();
            let phi = std::f64::consts::TAU * rng.uniform();
            let r = 0.1 + 5.0 * rng.uniform();
            let w: [f64; 3] = std::array::from_fn(|i| {
                theta.cos() * axis[i] + theta.sin() * (phi.cos() * u[i] + phi.sin() * v[i])
            });
            let x: [f64; 3] = std::array::from_fn(|i| position[i] + r * w[i]);
            // A normal facing the light, tilted.
            let n = normalize(std::array::from_fn(|i| -w[i] + 0.3 * (rng.uniform() - 0.5)));
            let a = incident_prepared(&fast, x, n, 100.0);
            let b = incident_prepared(&plain, x, n, 100.0);
            assert_eq!(
                a.map(|i| i.irradiance.map(f64::to_bits)),
                b.map(|i| i.irradiance.map(f64::to_bits)),
                "spot {case} (cone {cone}°, beam {beam}°), point {k} at {theta} rad"
            );
            let c = dot(axis, normalize(std::array::from_fn(|i| x[i] - position[i])));
            shortcut[if c < cos_outside {
                0
            } else if c > cos_inside {
                1
            } else {
                2
            }] += 1;
        }
    }
    // Both shortcuts and the acos all taken, many times each.
    assert!(shortcut.iter().all(|&s| s > 1000), "{shortcut:?}");
}

#[test]
fn random_lights_are_seeded_and_valid() {
    let b = ([0.0f32, 0.0, 0.0], [10.0f32, 3.0, 5.0]);
    let a = random_lights(b, 64, 7);
    assert_eq!(format!("{a:?}"), format!("{:?}", random_lights(b, 64, 7)));
    assert_ne!(format!("{a:?}"), format!("{:?}", random_lights(b, 64, 8)));
    for l in &a {
        let cfg = radiosity::core::scene_config::SceneConfig {
            objects: Vec::new(),
            sky: None,
            emission: Default::default(),
            camera: radiosity::core::scene_config::Camera {
                position: [0.0; 3],
                target: [0.0, 0.0, 1.0],
                up: [0.0, 1.0, 0.0],
                fov_y_deg: 45.0,
            },
            lights: vec![l.clone()],
            units: "m".into(),
            description: String::new(),
        };
        cfg.validate().unwrap();
    }
}

/// The direct pass's per-patch points, their shadow rays in packets of
/// eight (`DirectLight::at_points_each`, and `at_points` through it), and
/// the renderer's points one at a time with each light's last blocker tried
/// first (`at_point_cached`), give the same bits as the plain definition: per light, its incident
/// irradiance where a full BVH traversal (`visible`) finds no blocker. On a
/// floor under a roof, lit by random spot and directional lights, points
/// spread over the whole floor.
#[test]
fn packets_and_cached_blockers_change_no_bit_of_the_direct_light() {
    let (s, _) = floor(true);
    let dl = DirectLight::new(&s);
    let lights = random_lights(s.bounds(), 8, 5);
    let prepared = Prepared::all(&lights);
    let mut blocked = 0;
    let mut plain = |p: ([f64; 3], [f64; 3])| -> [f64; 3] {
        let (x, n) = p;
        let x: [f64; 3] = std::array::from_fn(|k| x[k] + n[k] * dl.offset());
        let mut d = [0.0; 3];
        for l in &lights {
            if let Some(inc) = incident(l, x, n, dl.far()) {
                if dl.visible(x, inc.shadow_end) {
                    for (dc, e) in d.iter_mut().zip(inc.irradiance) {
                        *dc += e;
                    }
                } else {
                    blocked += 1;
                }
            }
        }
        d
    };
    for row in 0..16 {
        // A row of points at z, x from −0.5 to 0.5: half under the roof.
        let z = -0.5 + (row as f64 + 0.5) / 16.0;
        let points: Vec<([f64; 3], [f64; 3])> = (0..24)
            .map(|i| ([-0.5 + (i as f64 + 0.5) / 24.0, 0.0, z], [0.0, 1.0, 0.0]))
            .collect();
        let each = dl.at_points_each(&points, &lights);
        // The renderer's path: one point at a time, each light's last
        // blocker along the row tried first.
        let mut cache = ShadowCache::new(lights.len());
        for (p, e) in points.iter().zip(&each) {
            let want = plain(*p).map(f64::to_bits);
            assert_eq!(want, e.map(f64::to_bits), "at {:?}", p.0);
            let cached = dl.at_point_cached(p.0, p.1, &prepared, &mut cache);
            assert_eq!(want, cached.map(f64::to_bits), "at {:?}, cached", p.0);
            let alone = dl.at_points(std::slice::from_ref(p), &lights);
            assert_eq!(want, alone.map(f64::to_bits), "at {:?} alone", p.0);
        }
    }
    assert!(
        blocked > 0,
        "some light is blocked somewhere: the cache is exercised"
    );
}

/// A point light exactly in a ceiling's plane (inside its outline) lights
/// the floor below as the inverse-square law says: the shadow segment
/// stops the rays' offset short of the light (`DirectLight::
/// shadow_segment`), so the ceiling does not block it at the segment's very
/// end. Before, rounding decided each ray there: the floor came out black,
/// speckled and striped (the original Cornell data's spot at the light
/// quad's height). Packets and the cached per-point path agree.
#[test]
fn a_light_in_a_surfaces_plane_is_not_shadowed_by_it() {
    // The ceiling at y = 0.5 over the whole floor, facing down.
    let s = scene::load(&common::floor_under_ceiling("in-plane")).unwrap();
    let v = voxelize_at(&s, 0.25, &Backend::Cpu).unwrap();
    let patches: Vec<_> = v
        .patches
        .into_iter()
        .filter(|p| p.normal[1] > 0.99)
        .collect();
    assert_eq!(patches.len(), 16);
    let dl = DirectLight::new(&s);
    let (lx, lz) = (0.1f64, -0.15f64);
    for light in [
        Light::Point {
            position: [lx as f32, 0.5, lz as f32],
            intensity: [1.0; 3],
        },
        Light::Spot {
            position: [lx as f32, 0.5, lz as f32],
            direction: [0.0, -1.0, 0.0],
            intensity: [1.0; 3],
            cone_angle_deg: 89.0,
            beam_angle_deg: 88.0,
        },
    ] {
        let d = dl.irradiance(&patches, std::slice::from_ref(&light));
        let prepared = Prepared::all(std::slice::from_ref(&light));
        let mut cache = ShadowCache::new(1);
        for (p, d) in patches.iter().zip(&d) {
            let h = 0.25 * p.area.sqrt();
            let mut e = 0.0;
            for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)] {
                let (x, z) = (p.centre[0] + h * a - lx, p.centre[2] + h * b - lz);
                let r2: f64 = x * x + z * z + 0.25;
                e += 0.5 / r2.powf(1.5) / 4.0;
                // The per-point path (the CPU renderer's) lights it too.
                let x = [p.centre[0] + h * a, 0.0, p.centre[2] + h * b];
                let one = dl.at_point_cached(x, [0.0, 1.0, 0.0], &prepared, &mut cache);
                assert!(one[0] > 0.0, "{light:?}: the point {x:?} is shadowed");
            }
            // The rays' offset (1e-4 of the extent) and the beam's edge at
            // 88° (beyond every sample point) are all that separate them.
            assert!(
                (d[0] - e).abs() <= 1e-3 * e,
                "{light:?}: patch at {:?}: {} against {e}",
                p.centre,
                d[0]
            );
        }
    }
}
