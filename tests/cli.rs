//! The command line as a user meets it: exit codes, `--json` outputs,
//! `-o`/`--export` files, and errors that name what is wrong.

mod common;

use std::process::{Command, Output};

fn radiosity(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_radiosity"))
        .args(args)
        .env_remove("RADIOSITY_CL_DEVICE")
        .output()
        .expect("running the radiosity binary")
}

/// `radiosity bake OBJ --patches N -o OUT`, which must succeed.
fn bake_ok(obj: &std::path::Path, patches: u32, out: &std::path::Path) {
    let o = radiosity(&[
        "bake",
        obj.to_str().unwrap(),
        "--patches",
        &patches.to_string(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn help_and_version() {
    let o = radiosity(&["--help"]);
    assert!(o.status.success());
    for sub in ["devices", "info", "bake", "generate", "bench"] {
        assert!(stdout(&o).contains(sub), "--help lists {sub}");
    }
    assert!(radiosity(&["--version"]).status.success());
    let o = radiosity(&["no-such-command"]);
    assert_eq!(o.status.code(), Some(2), "usage errors exit with 2 (clap)");
}

#[test]
fn devices_lists_the_opencl_device() {
    let o = radiosity(&["devices", "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let list = v.as_array().unwrap();
    assert!(!list.is_empty());
    assert!(list[0]["max_mem_alloc_bytes"].as_u64().unwrap() > 0);
    let o = radiosity(&["devices"]);
    assert!(stdout(&o).contains("[0]"));
}

#[test]
fn info_json_has_the_documented_keys() {
    let path = common::bundled("cornell_box");
    let o = radiosity(&["info", path.to_str().unwrap(), "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    for key in [
        "triangles",
        "materials",
        "bounds",
        "area",
        "emissive_area",
        "repairs",
        "winding",
    ] {
        assert!(v.get(key).is_some(), "key {key} missing in {v}");
    }
    assert_eq!(v["triangles"], 1834);
    assert_eq!(v["winding"]["faces_seen_from_behind"], 0);
    // A room with faces wound either way: `info` says where, before a bake.
    let mixed = common::mixed_winding_room(false);
    let o = radiosity(&["info", mixed.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = stdout(&o);
    assert!(
        text.contains("winding: 8 faces seen from behind") && text.contains("`m3`"),
        "{text}"
    );
    // The light quad: 130 mm × 105 mm.
    assert!((v["emissive_area"].as_f64().unwrap() - 13650.0).abs() < 1e-6);
    let o = radiosity(&["info", common::sponza().to_str().unwrap()]);
    assert!(o.status.success());
    assert!(stdout(&o).contains("66445"), "{}", stdout(&o));
}

#[test]
fn missing_scene_is_a_clear_error() {
    let o = radiosity(&["info", "/nonexistent/scene.obj"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("/nonexistent/scene.obj"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn bake_reports_counts_and_exports_patches() {
    let dir = common::temp_dir("cli-bake");
    let path = common::bundled("cornell_box");
    let o = radiosity(&[
        "bake",
        path.to_str().unwrap(),
        "--voxel-size",
        "50",
        "--export",
        dir.to_str().unwrap(),
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let patches = v["form_factors"]["kept"].as_u64().unwrap();
    assert!(patches > 100);
    assert!(patches <= v["voxels"]["patches"].as_u64().unwrap());
    let stages: Vec<&str> = v["stages"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["stage"].as_str().unwrap())
        .collect();
    assert_eq!(
        stages,
        [
            "load",
            "winding",
            "voxelize",
            "form factors",
            "transfer",
            "reorder",
            "encode",
            "mesh map",
            "surface map",
            "near field",
            "probes",
            "export"
        ]
    );
    // Each stage says where it ran: voxelization and transfer on the
    // OpenCL device, the rays form factors and the rest on the host.
    let device = |name: &str| -> String {
        v["stages"]
            .as_array()
            .unwrap()
            .iter()
            .find(|s| s["stage"] == name)
            .and_then(|s| s["device"].as_str())
            .unwrap()
            .to_string()
    };
    assert_eq!(device("voxelize"), v["device"].as_str().unwrap());
    assert_eq!(device("transfer"), v["device"].as_str().unwrap());
    assert!(
        device("form factors").starts_with("CPU ("),
        "{}",
        device("form factors")
    );
    assert!(device("encode").starts_with("CPU ("));
    assert!(v["output"].is_null(), "no -o, no file");
    assert!(v["codec"]["bytes_per_entry"].as_f64().unwrap() > 0.0);
    // The matrices, in the order of patches.csv.
    let n = patches as usize;
    let (shape, f) = radiosity::core::npy::read_f32(&dir.join("F.npy")).unwrap();
    assert_eq!(shape, [n, n]);
    assert!(f.iter().all(|x| x.is_finite() && *x >= 0.0));
    let (shape, t) = radiosity::core::npy::read_f32(&dir.join("T.npy")).unwrap();
    assert_eq!(shape, [3, n, n]);
    // The matrix as the run time sees it: same shape and order as T.npy,
    // and within the codec's error of it (relative Frobenius error a few
    // per cent for the default BC1 setting; docs/compression.md).
    let (shape, td) = radiosity::core::npy::read_f32(&dir.join("T_decoded.npy")).unwrap();
    assert_eq!(shape, [3, n, n]);
    let (d2, r2) = t.iter().zip(&td).fold((0.0, 0.0), |(d, r), (&a, &b)| {
        (d + (a as f64 - b as f64).powi(2), r + (a as f64).powi(2))
    });
    assert!(
        (d2 / r2).sqrt() < 0.1,
        "T_decoded is far from T: {}",
        (d2 / r2).sqrt()
    );
    let (shape, _) = radiosity::core::npy::read_f32(&dir.join("albedo.npy")).unwrap();
    assert_eq!(shape, [n, 3]);
    let csv = std::fs::read_to_string(dir.join("patches.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(
        lines.next().unwrap(),
        radiosity::bake::export::PATCHES_CSV_HEADER
    );
    assert_eq!(lines.count() as u64, patches);
    // The preview: the red wall (x = 550) is on the camera's left, the green
    // one (x = 0) on its right.
    let img = image::open(dir.join("patches.png")).unwrap().to_rgb8();
    let mean = |x0: u32, x1: u32| -> [f64; 3] {
        let mut s = [0.0; 3];
        let mut n = 0.0;
        for y in 150..450 {
            for x in x0..x1 {
                let p = img.get_pixel(x, y);
                for c in 0..3 {
                    s[c] += p[c] as f64;
                }
                n += 1.0;
            }
        }
        s.map(|v| v / n)
    };
    let (left, right) = (mean(100, 180), mean(620, 700));
    assert!(left[0] > 1.5 * left[1], "left side should be red: {left:?}");
    assert!(
        right[1] > 1.5 * right[0],
        "right side should be green: {right:?}"
    );
    // Progress goes to stderr, one line per stage.
    assert!(stderr(&o).contains("[bake] voxelizing"));
}

/// `bake -o` writes a `.rad` file that `info` describes with the
/// documented keys; the bounce count is a number or "inf".
#[test]
fn bake_writes_a_file_that_info_describes() {
    let dir = common::temp_dir("cli-rad");
    let scene = common::bundled("cornell_box");
    // The output's directory need not exist (the README's first command
    // writes into out/); an impossible one fails before the bake.
    let blocker = dir.join("file");
    std::fs::write(&blocker, b"").unwrap();
    let o = radiosity(&[
        "bake",
        scene.to_str().unwrap(),
        "-o",
        blocker.join("x.rad").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("cannot create the folder"),
        "{}",
        stderr(&o)
    );
    assert!(
        !stderr(&o).contains("[bake] voxelizing"),
        "failed before the bake"
    );
    for (bounces, expect) in [
        ("2", serde_json::json!(2)),
        ("inf", serde_json::json!("inf")),
    ] {
        let out = dir.join("new").join(format!("cornell-{bounces}.rad"));
        let o = radiosity(&[
            "bake",
            scene.to_str().unwrap(),
            "--voxel-size",
            "80",
            "--bounces",
            bounces,
            "--codec",
            "bc1:sparse=f16",
            "--top-fraction",
            "0.02",
            "--reorder",
            "hilbert",
            "--error-lights",
            "4",
            "-o",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        // The final summary.
        for line in [
            "summary",
            "bytes per matrix entry",
            "tiles skipped",
            "compression error",
        ] {
            assert!(
                stdout(&o).contains(line),
                "summary lacks {line:?}: {}",
                stdout(&o)
            );
        }
        let o = radiosity(&["info", out.to_str().unwrap(), "--json"]);
        assert!(o.status.success(), "{}", stderr(&o));
        let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
        for key in [
            "patches",
            "bounces",
            "codec",
            "bytes_per_entry",
            "bytes_dense",
            "bytes_sparse",
            "zero_tile_fraction",
        ] {
            assert!(!v[key].is_null(), "info --json lacks {key}: {v}");
        }
        assert_eq!(v["bounces"], expect);
        assert_eq!(v["codec"], "bc1-log(top=0.02,L=auto,f16)");
        assert_eq!(v["reorder"], "hilbert");
        assert_eq!(v["scene_status"], "unchanged");
        let n = v["patches"].as_f64().unwrap();
        let total = v["bytes_dense"].as_f64().unwrap()
            + v["bytes_sparse"].as_f64().unwrap()
            + v["bytes_index"].as_f64().unwrap();
        assert!((v["bytes_per_entry"].as_f64().unwrap() - total / (n * n)).abs() < 1e-12);
        let o = radiosity(&["info", out.to_str().unwrap()]);
        assert!(stdout(&o).contains("bytes per matrix entry"));
    }
    // A damaged file is refused with its name and the damaged section.
    let path = dir.join("new").join("cornell-2.rad");
    let mut bytes = std::fs::read(&path).unwrap();
    let k = bytes.len() - 100;
    bytes[k] ^= 0x40;
    let bad = dir.join("damaged.rad");
    std::fs::write(&bad, &bytes).unwrap();
    let o = radiosity(&["info", bad.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("damaged.rad"), "{}", stderr(&o));
    assert!(stderr(&o).contains("checksum"), "{}", stderr(&o));
    // Codec options that do not fit are usage errors with the flag's name.
    let o = radiosity(&[
        "bake",
        scene.to_str().unwrap(),
        "--codec",
        "f32",
        "--top-fraction",
        "0.1",
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("--top-fraction"), "{}", stderr(&o));
    let o = radiosity(&["bake", scene.to_str().unwrap(), "--codec", "png"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("png"), "{}", stderr(&o));
    let o = radiosity(&["bake", scene.to_str().unwrap(), "--reorder", "random"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("random"), "{}", stderr(&o));
}

#[test]
fn bake_sponza_with_a_patch_target() {
    // The count is of the patches the form factors keep (those that see
    // another surface: a quarter of Sponza's voxelization sees only the
    // sky); the later stages' settings do not change it, so they are the
    // cheapest (the default rays, near field, codec search and reordering
    // took 29 of the bake's 36 s).
    let o = radiosity(&[
        "bake",
        common::sponza().to_str().unwrap(),
        "--patches",
        "2000",
        "--ff-rays-per-patch",
        "256",
        "--near-field-rays",
        "0",
        "--codec",
        "f16",
        "--reorder",
        "none",
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let n = v["form_factors"]["kept"].as_f64().unwrap();
    let voxel = v["voxels"]["patches"].as_f64().unwrap();
    assert!((n / 2000.0 - 1.0).abs() < 0.1, "{n} patches kept");
    assert!(voxel > 1.2 * n, "{voxel} patches before the form factors");
}

#[test]
fn bad_options_and_devices_are_refused() {
    let path = common::bundled("cornell_box");
    let p = path.to_str().unwrap();
    for flag in [["--voxel-size=-1"].as_slice(), &["--voxel-size", "-1"]] {
        let o = radiosity(&[&["bake", p], flag].concat());
        assert_eq!(o.status.code(), Some(1));
        assert!(stderr(&o).contains("--voxel-size"), "{}", stderr(&o));
    }
    let o = radiosity(&["bake", p, "--patches", "0"]);
    assert_eq!(o.status.code(), Some(1));
    // Error lights each keep B0 through the compression search: a count
    // that would fill the memory is refused before the bake.
    let o = radiosity(&["bake", p, "--error-lights", "100000000"]);
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(
        e.contains("--error-lights") && e.contains("4096") && !e.contains("[bake]"),
        "{e}"
    );
    let o = radiosity(&["bake", p, "--near-field-rays", "70000"]);
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(
        e.contains("--near-field-rays") && e.contains("70000") && e.contains("65535"),
        "{e}"
    );
    for bad in ["2", "-0.1", "nan"] {
        let flag = format!("--near-field-min-form-factor={bad}");
        let o = radiosity(&["bake", p, &flag]);
        assert_eq!(o.status.code(), Some(1));
        let e = stderr(&o);
        assert!(
            e.contains("--near-field-min-form-factor") && e.contains("0..=1"),
            "{bad}: {e}"
        );
    }
    let o = radiosity(&["bake", p, "--device", "99"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("index 99"), "{}", stderr(&o));
    let o = Command::new(env!("CARGO_BIN_EXE_radiosity"))
        .args(["bake", p])
        .env("RADIOSITY_CL_DEVICE", "first")
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("RADIOSITY_CL_DEVICE"), "{}", stderr(&o));
}

#[test]
fn generate_writes_the_committed_scene() {
    let dir = common::temp_dir("cli-gen");
    let o = radiosity(&["generate", "cornell_box", "-o", dir.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    for ext in ["obj", "mtl", "json"] {
        let a = std::fs::read(dir.join(format!("cornell_box.{ext}"))).unwrap();
        let b = std::fs::read(common::bundled("cornell_box").with_extension(ext)).unwrap();
        assert!(a == b, "cornell_box.{ext} differs from the committed file");
    }
    let o = radiosity(&["generate", "nonexistent"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("cornell_box"),
        "the error lists the known names"
    );
}

/// `render` on a scene bakes it into the cache (then reuses it), writes a
/// PNG and a PFM whose pixels match, and refuses bad options clearly.
#[test]
fn render_bakes_or_reuses_and_writes_png_and_pfm() {
    let dir = common::temp_dir("cli-render");
    let src = common::bundled("cornell_box");
    for f in ["cornell_box.obj", "cornell_box.mtl", "cornell_box.json"] {
        std::fs::copy(src.with_file_name(f), dir.join(f)).unwrap();
    }
    let obj = dir.join("cornell_box.obj");
    let png = dir.join("out.png");
    let pfm = dir.join("out.pfm");
    let cache = dir.join("cache");
    let run = |extra: &[&str]| {
        let mut args = vec![
            "render",
            obj.to_str().unwrap(),
            "-o",
            png.to_str().unwrap(),
            "--patches",
            "400",
            "--width",
            "64",
            "--height",
            "48",
        ];
        args.extend_from_slice(extra);
        Command::new(env!("CARGO_BIN_EXE_radiosity"))
            .args(&args)
            .env("RADIOSITY_CACHE_DIR", &cache)
            .output()
            .unwrap()
    };
    let o = run(&["--hdr", pfm.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stderr(&o).contains("reusing"), "{}", stderr(&o));
    let img = image::open(&png).unwrap().to_rgb8();
    assert_eq!((img.width(), img.height()), (64, 48));
    assert!(img.pixels().any(|p| p[0] > 30), "the image is not black");
    let bytes = std::fs::read(&pfm).unwrap();
    assert!(bytes.starts_with(b"PF\n64 48\n-1.0\n"));
    assert_eq!(bytes.len(), b"PF\n64 48\n-1.0\n".len() + 64 * 48 * 12);
    // Second run: the cached bake is reused.
    let o = run(&["--view", "indirect"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("reusing"), "{}", stderr(&o));
    // The exposure printed, given back with --exposure, draws the same
    // PNG, also far from 1: under a light of 10³⁴ W/sr (four decimals had
    // printed 0.0000, which --exposure refuses).
    let bright = dir.join("bright.json");
    let json = std::fs::read_to_string(dir.join("cornell_box.json")).unwrap();
    assert!(json.contains("73863.81"), "the bundled spot's intensity");
    std::fs::write(&bright, json.replace("73863.81", "7.386381e34")).unwrap();
    for lights in [None, Some(bright.to_str().unwrap())] {
        let extra: Vec<&str> = lights.map_or(vec![], |l| vec!["--camera-lights", l]);
        let o = run(&extra);
        assert!(o.status.success(), "{}", stderr(&o));
        let printed = common::printed_exposure(&stderr(&o));
        let k: f32 = printed.parse().unwrap_or_else(|_| panic!("{printed:?}"));
        assert!(k > 0.0 && k.is_finite(), "{printed}");
        if lights.is_some() {
            assert!(
                k < 1e-20,
                "a light of 1e34 W/sr needs a tiny exposure: {printed}"
            );
        }
        let first = std::fs::read(&png).unwrap();
        let again = [extra.as_slice(), &["--exposure", &printed]].concat();
        let o = run(&again);
        assert!(o.status.success(), "{}", stderr(&o));
        assert!(
            first == std::fs::read(&png).unwrap(),
            "--exposure {printed} drew another image"
        );
    }
    // `auto` renders on GL where GL runs on a GPU, on the CPU where GL is
    // software (llvmpipe here) and says so.
    let o = run(&["--backend", "auto"]);
    let e = stderr(&o);
    assert!(o.status.success(), "{e}");
    if e.contains("OpenGL is software") {
        assert!(e.contains("\ncpu: ") && !e.contains("\ngl ("), "{e}");
    } else {
        assert!(e.contains("gl (") || e.contains("no OpenGL context"), "{e}");
    }
    // Bad options name the flag.
    let o = run(&["--view", "sideways"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("--view"), "{}", stderr(&o));
    let o = run(&["--samples", "0"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("--samples"), "{}", stderr(&o));
    // Culling: a fraction in [0, 1), negative numbers and NaN refused.
    for bad in ["nan", "-0.5", "1", "inf"] {
        let o = run(&["--cull", bad]);
        assert_eq!(o.status.code(), Some(1), "{bad}");
        assert!(stderr(&o).contains("--cull"), "{bad}: {}", stderr(&o));
    }
    let o = run(&["--cull", "0.001"]);
    assert!(o.status.success(), "{}", stderr(&o));
    // An image whose pixel count overflows (2^32 × 2^32 wrapped to 0 and
    // passed the check, then a row took 48 GB) or exceeds 2^26 is refused
    // (before any bake).
    for size in [
        ["4294967296", "4294967296"],
        ["100000", "100000"],
        ["0", "10"],
    ] {
        let o = radiosity(&[
            "render",
            obj.to_str().unwrap(),
            "-o",
            png.to_str().unwrap(),
            "--width",
            size[0],
            "--height",
            size[1],
        ]);
        assert_eq!(o.status.code(), Some(1), "{size:?}");
        assert!(
            stderr(&o).contains("2^26 pixels"),
            "{size:?}: {}",
            stderr(&o)
        );
    }
    // A fixed exposure that is not a positive finite factor would write a
    // black or white image; it is refused, negative numbers included
    // (given as a value, not taken for a flag).
    for bad in ["nan", "inf", "0", "-1"] {
        let o = run(&["--exposure", bad]);
        assert_eq!(o.status.code(), Some(1), "{bad}");
        assert!(
            stderr(&o).contains("--exposure") && stderr(&o).contains("positive finite"),
            "{bad}: {}",
            stderr(&o)
        );
    }
    // A scene without its camera-and-lights file gets a default one, said
    // on stderr; a file that is named but missing is an error naming it.
    std::fs::remove_file(dir.join("cornell_box.json")).unwrap();
    std::fs::remove_file(&png).unwrap();
    let o = run(&[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("no camera-and-lights file")
            && stderr(&o).contains("default for cornell_box.obj"),
        "{}",
        stderr(&o)
    );
    let img = image::open(&png).unwrap().to_rgb8();
    assert!(img.pixels().any(|p| p[0] > 30), "the default view is black");
    let missing = dir.join("missing.json");
    let o = run(&["--camera-lights", missing.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("missing.json"), "{}", stderr(&o));
    // A mistake in the scene's own camera-and-lights file stops the command
    // before a bake (which would take minutes on a large scene): with an
    // empty cache, nothing is baked and the message names the field.
    let text = std::fs::read_to_string(src.with_file_name("cornell_box.json")).unwrap();
    let bad = text.replace("\"cone_angle_deg\": 60.0", "\"cone_angle_deg\": 200.0");
    assert_ne!(bad, text, "the bundled file's cone angle moved");
    std::fs::write(dir.join("cornell_box.json"), bad).unwrap();
    let empty_cache = dir.join("empty-cache");
    let o = Command::new(env!("CARGO_BIN_EXE_radiosity"))
        .args(["render", obj.to_str().unwrap(), "-o", png.to_str().unwrap()])
        .env("RADIOSITY_CACHE_DIR", &empty_cache)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("cone_angle_deg") && !stderr(&o).contains("[bake]"),
        "{}",
        stderr(&o)
    );
    assert!(!empty_cache.exists(), "a bake was started");
}

/// `info` on a file named `.rad` that is not a bake file says so (it does
/// not try it as an OBJ).
#[test]
fn info_on_a_non_bake_rad_file_says_so() {
    let dir = common::temp_dir("cli-notrad");
    let f = dir.join("x.rad");
    std::fs::write(&f, b"abcd").unwrap();
    let o = radiosity(&["info", f.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("not a radiosity bake file"),
        "{}",
        stderr(&o)
    );
}

/// A closed unit box whose faces point out (normals away from the inside).
const OUTWARD_BOX: &str =
    "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n";

#[test]
fn refused_bakes_exit_1_and_write_nothing() {
    let dir = common::temp_dir("cli-refused");
    let obj = dir.join("box.obj");
    std::fs::write(&obj, OUTWARD_BOX).unwrap();
    let out_dir = dir.join("out");
    let out = out_dir.join("x.rad");
    let (obj_s, out_s) = (obj.to_str().unwrap(), out.to_str().unwrap());
    // Beyond the format (32-bit entry indices), and beyond any machine's
    // memory below ~170 GB: refused before voxelizing, with the numbers.
    for (patches, says) in [("5000000", "at most 65535"), ("65000", "patches fit")] {
        let o = radiosity(&["bake", obj_s, "--patches", patches, "-o", out_s]);
        assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
        assert!(stderr(&o).contains(says), "{}", stderr(&o));
        assert!(!out_dir.exists(), "nothing is written");
    }
    // Wound outward: the cause and the remedy.
    let o = radiosity(&["bake", obj_s, "--patches", "200", "-o", out_s]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(e.contains("wound away") && e.contains("--two-sided"), "{e}");
    assert!(!out.exists());
    // Two-sided it bakes, and info says so.
    let o = radiosity(&[
        "bake",
        obj_s,
        "--patches",
        "200",
        "--two-sided",
        "-o",
        out_s,
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = radiosity(&["info", out_s]);
    assert!(stdout(&o).contains("two-sided"), "{}", stdout(&o));
}

#[test]
fn info_finds_the_scene_from_another_directory() {
    // The stored scene path is relative to the bake file, not to where
    // info runs.
    let dir = common::temp_dir("cli-info-elsewhere");
    let scene_dir = dir.join("scene");
    std::fs::create_dir_all(&scene_dir).unwrap();
    let obj = scene_dir.join("box.obj");
    // The box wound inward (the faces of OUTWARD_BOX reversed).
    let inward: String = OUTWARD_BOX
        .lines()
        .map(|l| match l.strip_prefix("f ") {
            Some(f) => format!("f {}\n", f.split(' ').rev().collect::<Vec<_>>().join(" ")),
            None => format!("{l}\n"),
        })
        .collect();
    std::fs::write(&obj, inward).unwrap();
    let rad = dir.join("bakes").join("box.rad");
    bake_ok(&obj, 150, &rad);
    let elsewhere = common::temp_dir("cli-info-cwd");
    let o = Command::new(env!("CARGO_BIN_EXE_radiosity"))
        .args(["info", rad.to_str().unwrap()])
        .current_dir(&elsewhere)
        .env_remove("RADIOSITY_CL_DEVICE")
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let text = stdout(&o);
    // Stored as `../scene/box.obj` beside the bake; named without the
    // `bakes/..` detour (the same file).
    let looked = dir.join("scene/box.obj");
    assert!(
        text.contains(&format!("looked for at {}: unchanged", looked.display())),
        "{text}"
    );
}

/// `bench frame` runs to the end on a small bake and prints every table
/// the README quotes: the CPU stages, the gather's share of the measured
/// bandwidth, the GL frame with both patch lights, and classic radiosity
/// with its error against the exact `T_∞ B0` (so a benchmark that breaks
/// shows here, not in the next README update).
#[test]
fn bench_frame_prints_its_tables() {
    let obj = common::bundled_copy("cornell_box", "cli-bench-frame");
    let rad = obj.with_file_name("cb.rad");
    bake_ok(&obj, 300, &rad);
    let o = radiosity(&[
        "bench",
        "frame",
        rad.to_str().unwrap(),
        "--repeat",
        "1",
        "--width",
        "64",
        "--height",
        "48",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = stdout(&o);
    let o = radiosity(&[
        "bench",
        "frame",
        rad.to_str().unwrap(),
        "--width",
        "4294967296",
        "--height",
        "4294967296",
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("2^26 pixels"), "{}", stderr(&o));
    for row in [
        "| frame, nothing reused |",
        "| gather, every column |",
        "% of bandwidth",
        "| gather, one spot light",
        "| that spot light, negligible columns culled",
        "| that term with negligible columns culled",
        "GL frame on",
        "| H from the CPU run time (`view --patch-light cpu`) |",
        "+ the CPU frame",
        "| classic, 3 bounces |",
        "| classic ∞ (Jacobi",
        "the scene's lights gathered with negligible columns culled",
    ] {
        assert!(out.contains(row), "no {row:?} in:\n{out}");
    }
    // The culled rows' L1 error within their bound (both printed to 4
    // decimals of a per cent: one unit of the last digit of slack; and
    // the products' f32 rounding, γ_n ≈ 2·10⁻⁵ of the total at n ≈ 300).
    for line in out
        .lines()
        .filter(|l| l.starts_with("| that") && l.contains("negligible columns culled"))
    {
        let num = |after: &str| -> f64 {
            let rest = &line[line
                .find(after)
                .unwrap_or_else(|| panic!("{after} in {line}"))
                + after.len()..];
            rest.split(|c: char| c != '.' && !c.is_ascii_digit())
                .next()
                .unwrap()
                .parse()
                .unwrap()
        };
        let (l1, bound) = (num("RMS, "), num("(bound "));
        assert!(l1 <= bound + 1e-4 + 2e-3, "{line}");
    }
}

/// Values that gave garbage with exit 0 are refused with exit 1, naming
/// the field or option, and write nothing: a light of 1e38 W/sr (a NaN
/// image), a camera at x = 1e38 (a black one), an emission scale that
/// overflows f32 (infinite pixels: the image check), a billion bounces
/// (never finished).
#[test]
fn values_that_gave_garbage_are_refused() {
    let obj = common::bundled_copy("cornell_box", "cli-garbage");
    let dir = obj.parent().unwrap().to_path_buf();
    let rad = dir.join("cb.rad");
    bake_ok(&obj, 150, &rad);
    let json = std::fs::read_to_string(obj.with_extension("json")).unwrap();
    let mut config: serde_json::Value = serde_json::from_str(&json).unwrap();
    let cases: Vec<(&str, serde_json::Value, &str)> = vec![
        (
            "huge",
            {
                let mut c = config.clone();
                c["lights"][0]["intensity"] = serde_json::json!([1e38, 1e38, 1e38]);
                c
            },
            "lights[0].intensity",
        ),
        (
            "far",
            {
                let mut c = config.clone();
                c["camera"]["position"][0] = serde_json::json!(1e38);
                c
            },
            "camera.position",
        ),
        (
            "emission",
            {
                let mut c = config.clone();
                c["emission"] = serde_json::json!({"light": 1e38});
                c
            },
            "infinite or NaN",
        ),
    ];
    for (name, c, says) in cases {
        let path = dir.join(format!("{name}.json"));
        std::fs::write(&path, serde_json::to_string(&c).unwrap()).unwrap();
        let png = dir.join(format!("{name}.png"));
        for backend in ["cpu", "gl"] {
            let o = radiosity(&[
                "render",
                rad.to_str().unwrap(),
                "--camera-lights",
                path.to_str().unwrap(),
                "-o",
                png.to_str().unwrap(),
                "--hdr",
                png.with_extension("pfm").to_str().unwrap(),
                "--width",
                "48",
                "--height",
                "36",
                "--backend",
                backend,
            ]);
            assert_eq!(
                o.status.code(),
                Some(1),
                "{name} on {backend}: {}",
                stderr(&o)
            );
            assert!(stderr(&o).contains(says), "{name}: {}", stderr(&o));
            assert!(
                !png.exists() && !png.with_extension("pfm").exists(),
                "{name}: written"
            );
        }
    }
    // The same file with sane values renders.
    config["lights"][0]["intensity"] = serde_json::json!([7e4, 5e4, 2e4]);
    let ok = dir.join("ok.json");
    std::fs::write(&ok, serde_json::to_string(&config).unwrap()).unwrap();
    let png = dir.join("ok.png");
    let o = radiosity(&[
        "render",
        rad.to_str().unwrap(),
        "--camera-lights",
        ok.to_str().unwrap(),
        "-o",
        png.to_str().unwrap(),
        "--width",
        "48",
        "--height",
        "36",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    // Bounces: refused at once, pointing to inf.
    let t = std::time::Instant::now();
    let o = radiosity(&["bake", obj.to_str().unwrap(), "--bounces", "1000000000"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("--bounces") && stderr(&o).contains("inf"),
        "{}",
        stderr(&o)
    );
    assert!(t.elapsed().as_secs_f64() < 10.0);
}
