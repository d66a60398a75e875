//! The camera and lights made for a scene without its `NAME.json`
//! (`core::default_view`), on generated scenes that are not kind: rooms
//! turned off the axes and placed far from the origin, big untessellated
//! quads, a thin wall, millimetres and kilometres, a courtyard open to the
//! sky, a lone quad facing away from the preferred side, a box wound
//! outward. What a user needs of a default is checked, not where it lands:
//! the configuration validates, the eye is where it should be (inside the
//! room, clear of solids, or outside a model), the middle of the view meets
//! the front of a surface, and that surface receives direct light.

mod common;

use common::{quad, write_quads, Quad};
use radiosity::core::default_view::{default_config, Placement};
use radiosity::core::direct::DirectLight;
use radiosity::core::scene::{self, Scene};
use radiosity::core::scene_config::{Light, SceneConfig};

const GREY: [f64; 3] = [0.6, 0.6, 0.6];

/// A frame turned by `yaw` about `+y`: `(ex, ey, ez)`, right-handed.
fn frame(yaw: f64) -> [[f64; 3]; 3] {
    let (s, c) = yaw.sin_cos();
    [[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The faces of a box (centre `c`, axes `e`, half sizes `h`), one quad each,
/// facing in (a room) or out (a solid). `skip_top` leaves the `+y` face out.
fn boxed(c: [f64; 3], e: [[f64; 3]; 3], h: [f64; 3], inward: bool, skip_top: bool) -> Vec<Quad> {
    let mut out = Vec::new();
    for a in 0..3 {
        for sign in [-1.0, 1.0] {
            if skip_top && a == 1 && sign > 0.0 {
                continue;
            }
            let centre: [f64; 3] = std::array::from_fn(|k| c[k] + sign * h[a] * e[a][k]);
            let out_n = e[a].map(|x| sign * x);
            let n = if inward { out_n.map(|x| -x) } else { out_n };
            let (b, d) = ((a + 1) % 3, (a + 2) % 3);
            let u = e[b];
            let v = cross(n, u);
            out.push(quad(centre, u, v, h[b], h[d], GREY));
        }
    }
    out
}

fn load(tag: &str, quads: &[Quad]) -> Scene {
    scene::load(&write_quads(tag, quads)).expect("the generated scene loads")
}

/// `p` in the frame (`c`, `e`).
fn local(p: [f64; 3], c: [f64; 3], e: [[f64; 3]; 3]) -> [f64; 3] {
    let d = [p[0] - c[0], p[1] - c[1], p[2] - c[2]];
    e.map(|a| a[0] * d[0] + a[1] * d[1] + a[2] * d[2])
}

/// The surface in the middle of the view: whether it faces the eye, and
/// the direct irradiance it receives from the configuration's lights.
fn middle_of_view(scene: &Scene, config: &SceneConfig) -> (bool, f64) {
    let direct = DirectLight::new(scene);
    let bvh = direct.bvh();
    let o = config.camera.position.map(f64::from);
    let t = config.camera.target.map(f64::from);
    let d: [f64; 3] = std::array::from_fn(|k| t[k] - o[k]);
    let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    let far = 10.0 * direct.far();
    let d = d.map(|x| x / len);
    let (k, s) = bvh
        .closest_hit(o, d.map(|x| x * far))
        .expect("the middle of the view meets a surface");
    let tri = bvh.order[k as usize] as usize;
    let n = scene.triangle_normal(tri);
    let front = n[0] * d[0] + n[1] * d[1] + n[2] * d[2] < 0.0;
    let x: [f64; 3] = std::array::from_fn(|i| o[i] + s * far * d[i]);
    let e = direct.at_points(&[(x, n)], &config.lights);
    (front, e.iter().sum::<f64>())
}

/// Asserts that the middle of the view is the front of a surface and that
/// it is lit (`what` names the case in messages).
fn assert_sees_a_lit_front(scene: &Scene, config: &SceneConfig, what: &str) {
    let (front, lit) = middle_of_view(scene, config);
    assert!(
        front,
        "{what}: the middle of the view is the back of a surface"
    );
    assert!(lit > 0.0, "{what}: the middle of the view is not lit");
}

/// A room 3.3 × 2.7 × 4.1 (in units of `s`) turned 17° and placed far from
/// the origin, split by a wall 2 mm thick with a door gap above it, a block
/// standing in the larger part: the eye inside one part, clear of the
/// walls and the block, under a point light, looking at a lit front.
#[test]
fn a_closed_room_gets_an_eye_inside_and_a_light_under_its_ceiling() {
    for s in [1e-3, 1.0, 1e3] {
        let e = frame(17f64.to_radians());
        let c = [1037.0 * s, -202.0 * s, 551.0 * s];
        let half = [1.65 * s, 1.35 * s, 2.05 * s];
        let mut quads = boxed(c, e, half, true, false);
        // The thin wall at local x = 0.37 s, 2.4 s high (a gap above).
        let wc: [f64; 3] = std::array::from_fn(|k| c[k] + 0.37 * s * e[0][k] - 0.15 * s * e[1][k]);
        quads.extend(boxed(wc, e, [0.001 * s, 1.2 * s, 2.05 * s], false, false));
        // The block in the part beyond the wall.
        let bc: [f64; 3] = std::array::from_fn(|k| c[k] + 1.0 * s * e[0][k] - 0.95 * s * e[1][k]);
        quads.extend(boxed(bc, e, [0.3 * s, 0.4 * s, 0.5 * s], false, false));
        let scene = load("default-room", &quads);
        let (config, placement) = default_config(&scene);
        config.validate().expect("the default validates");
        assert_eq!(
            placement,
            Placement::InsidePoint,
            "scale {s}: {}",
            config.description
        );
        let eye = local(config.camera.position.map(f64::from), c, e);
        for a in 0..3 {
            assert!(
                eye[a].abs() < half[a] - 0.05 * s,
                "scale {s}: the eye {eye:?} (room frame) is not inside the room"
            );
        }
        assert!(
            (eye[0] - 0.37 * s).abs() > 0.05 * s,
            "scale {s}: the eye {eye:?} is in the thin wall"
        );
        let in_block =
            (eye[0] - 1.0 * s).abs() < 0.35 * s && (eye[2]).abs() < 0.55 * s && eye[1] < -0.5 * s;
        assert!(!in_block, "scale {s}: the eye {eye:?} is in the block");
        let Light::Point { position, .. } = config.lights[0] else {
            panic!("scale {s}: expected a point light, got {:?}", config.lights)
        };
        let light = local(position.map(f64::from), c, e);
        for a in 0..3 {
            assert!(
                light[a].abs() < half[a],
                "scale {s}: the light {light:?} is not inside the room"
            );
        }
        assert_sees_a_lit_front(&scene, &config, &format!("scale {s}"));
    }
}

/// Walls and a floor open to the sky: the eye inside, lit by a sun.
#[test]
fn a_courtyard_open_above_gets_a_sun() {
    let e = frame(-0.4);
    let c = [-50.0, 7.0, 20.0];
    let quads = boxed(c, e, [6.0, 2.5, 4.5], true, true);
    let scene = load("default-yard", &quads);
    let (config, placement) = default_config(&scene);
    config.validate().expect("the default validates");
    assert_eq!(placement, Placement::InsideSun, "{}", config.description);
    let Light::Directional { direction, .. } = config.lights[0] else {
        panic!("expected a sun, got {:?}", config.lights)
    };
    assert!(
        direction[1] < -0.9,
        "the sun {direction:?} does not come from above"
    );
    assert_sees_a_lit_front(&scene, &config, "courtyard");
}

/// Models with no inside: one quad facing `-z` (away from the preferred
/// side), and a lone box wound outward. The eye goes outside their bounds
/// and sees a lit front.
#[test]
fn models_without_an_inside_are_framed_from_outside() {
    let lone = vec![quad(
        [3.0, 1.0, -2.0],
        [-1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        2.0,
        1.0,
        GREY,
    )];
    let solid = boxed([0.2, 0.5, 0.1], frame(0.3), [0.7, 0.5, 0.4], false, false);
    for (tag, quads) in [("quad", lone), ("solid", solid)] {
        let scene = load("default-outside", &quads);
        let (config, placement) = default_config(&scene);
        config.validate().expect("the default validates");
        assert_eq!(
            placement,
            Placement::Outside,
            "{tag}: {}",
            config.description
        );
        let (lo, hi) = scene.bounds();
        let p = config.camera.position;
        assert!(
            (0..3).any(|a| p[a] < lo[a] || p[a] > hi[a]),
            "{tag}: the eye {p:?} is within the bounds"
        );
        assert_sees_a_lit_front(&scene, &config, tag);
    }
}

/// "The default camera looks at the scene's largest open space" (issue
/// 42): a hall 24 × 5 × 7 m turned 33°, cluttered with 40 blocks on its
/// floor, beside a closed small room 4 × 3 × 4 m. The eye stands in the
/// hall, looks along its length (within 30°), and the
/// middle of the view is at least half the hall's length away: not into a
/// corner, a wall or the clutter.
#[test]
fn the_eye_looks_along_the_largest_open_space() {
    let e = frame(33f64.to_radians());
    let c = [120.0, 3.0, -40.0];
    let half = [12.0, 2.5, 3.5];
    let mut quads = boxed(c, e, half, true, false);
    // The small room beyond the hall's +z wall, a closed box of its own.
    let rc: [f64; 3] =
        std::array::from_fn(|k| c[k] + 6.0 * e[0][k] - 1.0 * e[1][k] + 5.5 * e[2][k]);
    quads.extend(boxed(rc, e, [2.0, 1.5, 2.0], true, false));
    for i in 0..40 {
        let x = -10.0 + 0.5 * i as f64;
        let z = -2.5 + 5.0 * ((i * 7 % 11) as f64 / 11.0);
        let bc: [f64; 3] =
            std::array::from_fn(|k| c[k] + x * e[0][k] - 2.2 * e[1][k] + z * e[2][k]);
        quads.extend(boxed(bc, e, [0.2, 0.3, 0.2], false, false));
    }
    let scene = load("default-hall", &quads);
    let (config, placement) = default_config(&scene);
    config.validate().expect("the default validates");
    assert_eq!(placement, Placement::InsidePoint, "{}", config.description);
    let eye = local(config.camera.position.map(f64::from), c, e);
    for a in 0..3 {
        assert!(
            eye[a].abs() < half[a],
            "the eye {eye:?} (hall frame) is not in the hall"
        );
    }
    let o = config.camera.position.map(f64::from);
    let t = config.camera.target.map(f64::from);
    let d = local(t, o, e);
    let horizontal = (d[0] * d[0] + d[2] * d[2]).sqrt();
    assert!(
        d[0].abs() / horizontal > 30f64.to_radians().cos(),
        "the view {d:?} (hall frame) is not along the hall"
    );
    let direct = DirectLight::new(&scene);
    let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    let dir: [f64; 3] = std::array::from_fn(|k| (t[k] - o[k]) / len);
    let far = 10.0 * direct.far();
    let (_, s) = direct
        .bvh()
        .closest_hit(o, dir.map(|x| x * far))
        .expect("the middle of the view meets a surface");
    assert!(
        s * far > half[0],
        "the middle of the view is {:.2} m away, under half the hall's length",
        s * far
    );
    assert_sees_a_lit_front(&scene, &config, "hall");
}
