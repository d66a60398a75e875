//! Lights and camera: photometric units by hand, the start view, and the
//! commands on a `.glb` (a JSON beside it overriding the file's view).

use super::builder::*;
use super::common::temp_dir;
use radiosity::core::light::incident;
use radiosity::core::scene;
use radiosity::core::scene_config::Light;
use serde_json::json;
use std::process::Command;

// ---------------------------------------------------------------------------
// Lights and camera

#[test]
fn lights_convert_photometric_units_and_the_camera_is_the_start_view() {
    let dir = temp_dir("gltf-lights");
    let mut b = Builder::new();
    // A floor: the unit quad turned to face +y (rotation −90° about x:
    // +z → +y), centred under the lights.
    let quad = unit_quad(&mut b, None);
    let mesh = b.mesh(vec![quad]);
    let h = std::f64::consts::FRAC_1_SQRT_2;
    let down = json!([-h, 0.0, 0.0, h]); // −z → −y
    b.json["extensionsUsed"] = json!(["KHR_lights_punctual"]);
    b.json["extensions"] = json!({"KHR_lights_punctual": {"lights": [
        {"type": "point", "intensity": 683.0, "color": [1.0, 0.5, 0.25]},
        {"type": "spot", "intensity": 1366.0, "spot": {"innerConeAngle": 0.2, "outerConeAngle": 0.5}, "range": 10.0},
        {"type": "directional", "intensity": 1366.0}
    ]}});
    b.push(
        "nodes",
        json!({"mesh": mesh, "translation": [-0.5, 0.0, 0.5], "rotation": [-h, 0.0, 0.0, h]}),
    );
    b.push("nodes", json!({"translation": [0.0, 2.0, 0.0], "extensions": {"KHR_lights_punctual": {"light": 0}}}));
    b.push("nodes", json!({"translation": [0.0, 3.0, 0.0], "rotation": down, "extensions": {"KHR_lights_punctual": {"light": 1}}}));
    b.push(
        "nodes",
        json!({"rotation": down, "extensions": {"KHR_lights_punctual": {"light": 2}}}),
    );
    b.push(
        "cameras",
        json!({"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1}}),
    );
    b.push(
        "nodes",
        json!({"translation": [0.0, 1.0, 5.0], "camera": 0}),
    );
    b.push("scenes", json!({"nodes": [0, 1, 2, 3, 4]}));
    let path = dir.join("lit.gltf");
    b.write_gltf(&path);
    let s = scene::load(&path).unwrap();
    // The quaternion's numbers are read as f32: 1e-7 rounding.
    assert!(close3(s.triangle_normal(0), [0.0, 1.0, 0.0], 1e-6));
    assert_eq!(s.authored.lights.len(), 3);
    assert!(
        s.warnings.iter().any(|w| w.contains("range")),
        "{:?}",
        s.warnings
    );
    // Irradiance at the floor's centre (0, 0, 0) facing up, by hand:
    // point 683 cd / 683 at 2 m: 1/4 W/m² × colour; spot 1366 cd on its
    // axis at 3 m: 2/9; sun of 1366 lx straight down: 2 W/m².
    let x = [0.0, 0.0, 0.0];
    let n = [0.0, 1.0, 0.0];
    let e = |l: &Light| {
        incident(l, x, n, 100.0)
            .map(|i| i.irradiance)
            .unwrap_or([0.0; 3])
    };
    let want = [[0.25, 0.125, 0.0625], [2.0 / 9.0; 3], [2.0; 3]];
    for (l, w) in s.authored.lights.iter().zip(want) {
        assert!(close3(e(l), w, 1e-6), "{l:?}: {:?} vs {w:?}", e(l));
    }
    match &s.authored.lights[1] {
        Light::Spot {
            cone_angle_deg,
            beam_angle_deg,
            ..
        } => {
            assert!((f64::from(*cone_angle_deg) - 0.5f64.to_degrees()).abs() < 1e-4);
            assert!((f64::from(*beam_angle_deg) - 0.2f64.to_degrees()).abs() < 1e-4);
        }
        other => panic!("{other:?}"),
    }
    // The camera, and the configuration a command starts from.
    let config = radiosity::core::default_view::config_for(&s);
    let c = &config.camera;
    assert!(close3(c.position.map(f64::from), [0.0, 1.0, 5.0], 1e-6));
    let d: Vec<f64> = (0..3)
        .map(|k| f64::from(c.target[k] - c.position[k]))
        .collect();
    assert!(
        d[0].abs() < 1e-6 && d[1].abs() < 1e-6 && d[2] < 0.0,
        "looks down −z: {d:?}"
    );
    assert!((f64::from(c.fov_y_deg) - 0.8f64.to_degrees()).abs() < 1e-4);
    assert_eq!(config.lights, s.authored.lights);
    assert!(
        config.description.contains("lit.gltf"),
        "{}",
        config.description
    );
}

#[test]
fn view_and_render_use_the_files_camera_and_lights_and_a_json_overrides_them() {
    let dir = temp_dir("gltf-cli");
    let mut b = Builder::new();
    let mesh = room(
        &mut b,
        json!({"name": "lamp", "emissiveFactor": [0.0, 0.0, 0.0],
               "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1.0], "metallicFactor": 0.0}}),
    );
    b.json["extensionsUsed"] = json!(["KHR_lights_punctual"]);
    b.json["extensions"] =
        json!({"KHR_lights_punctual": {"lights": [{"type": "point", "intensity": 100.0}]}});
    b.push("nodes", json!({"mesh": mesh}));
    b.push("nodes", json!({"translation": [1.0, 1.5, 1.0], "extensions": {"KHR_lights_punctual": {"light": 0}}}));
    b.push(
        "cameras",
        json!({"type": "perspective", "perspective": {"yfov": 1.0, "znear": 0.01}}),
    );
    b.push(
        "nodes",
        json!({"translation": [1.0, 1.0, 1.9], "camera": 0}),
    );
    b.push("scenes", json!({"nodes": [0, 1, 2]}));
    let glb = dir.join("room.glb");
    std::fs::write(&glb, b.glb_bytes()).unwrap();
    let bin = env!("CARGO_BIN_EXE_radiosity");
    let run = |args: &[&str]| {
        let out = Command::new(bin).args(args).output().unwrap();
        assert!(
            out.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        format!(
            "{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        )
    };
    let rad = dir.join("room.rad");
    let said = run(&[
        "bake",
        glb.to_str().unwrap(),
        "--patches",
        "100",
        "-o",
        rad.to_str().unwrap(),
    ]);
    // The voxel size in metres, the unit glTF fixes.
    assert!(said.contains(" m, grid "), "{said}");
    let png = dir.join("a.png");
    let render = || {
        run(&[
            "render",
            rad.to_str().unwrap(),
            "-o",
            png.to_str().unwrap(),
            "--width",
            "64",
            "--height",
            "48",
        ])
    };
    let said = render();
    assert!(
        said.contains("the camera and 1 light(s) of room.glb"),
        "{said}"
    );
    // A camera-and-lights file beside the scene wins.
    std::fs::write(
        dir.join("room.json"),
        r#"{"camera": {"position": [1, 1, 1], "target": [0, 1, 1], "up": [0, 1, 0], "fov_y_deg": 60},
            "lights": [{"type": "point", "position": [1, 1.5, 1], "intensity": [1, 1, 1]}], "units": "m"}"#,
    )
    .unwrap();
    let said = render();
    assert!(!said.contains("light(s) of room.glb"), "{said}");
    // The Mitsuba export takes it too: the room's meshes and its light.
    let said = run(&[
        "export-mitsuba",
        glb.to_str().unwrap(),
        "-o",
        dir.join("mitsuba").to_str().unwrap(),
    ]);
    assert!(said.contains("1 lights"), "{said}");
    assert!(dir.join("mitsuba/scene.xml").is_file());
    // `info` on the .glb reports metres and the file's view.
    let out = Command::new(bin)
        .args(["info", glb.to_str().unwrap()])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("(metres)") && text.contains("a camera, 1 light(s) from the file"),
        "{text}"
    );
}
