//! No command destroys an input (`src/outputs.rs`): an output that is the
//! scene's OBJ, one of its MTL libraries or textures, the camera-and-lights
//! file or the bake — by the same path, another spelling, a symbolic or a
//! hard link — is refused before any work with exit 1, naming the flag and
//! the input, and every input's bytes stay as they were; an image's format
//! follows its name or is refused; an output folder that cannot be made is
//! found before the bake, not after it.

mod common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn radiosity(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_radiosity"))
        .args(args)
        .env_remove("RADIOSITY_CL_DEVICE")
        // `view --headless-to` renders headless only without a display.
        .env_remove("DISPLAY")
        .output()
        .expect("running the radiosity binary")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A small textured room (the floor textured), its MTL, texture and
/// camera-and-lights file in a fresh folder; returns the folder.
fn textured_room(tag: &str) -> PathBuf {
    let dir = common::temp_dir(tag);
    let img = image::RgbImage::from_fn(8, 8, |x, y| {
        image::Rgb(if (x + y) % 2 == 0 {
            [60, 60, 60]
        } else {
            [200, 180, 160]
        })
    });
    img.save(dir.join("floor.png")).unwrap();
    let mut obj = String::from("mtllib room.mtl\n");
    let (sx, sy, sz) = (2.0, 1.5, 2.5);
    let faces: [([[f64; 3]; 4], &str); 6] = [
        (
            [[0., 0., 0.], [0., 0., sz], [sx, 0., sz], [sx, 0., 0.]],
            "floor",
        ),
        (
            [[0., sy, 0.], [sx, sy, 0.], [sx, sy, sz], [0., sy, sz]],
            "wall",
        ),
        (
            [[0., 0., 0.], [sx, 0., 0.], [sx, sy, 0.], [0., sy, 0.]],
            "wall",
        ),
        (
            [[0., 0., sz], [0., sy, sz], [sx, sy, sz], [sx, 0., sz]],
            "wall",
        ),
        (
            [[0., 0., 0.], [0., sy, 0.], [0., sy, sz], [0., 0., sz]],
            "wall",
        ),
        (
            [[sx, 0., 0.], [sx, 0., sz], [sx, sy, sz], [sx, sy, 0.]],
            "wall",
        ),
    ];
    for (k, (c, m)) in faces.iter().enumerate() {
        for v in c {
            obj += &format!("v {} {} {}\n", v[0], v[1], v[2]);
        }
        for uv in ["0 0", "1 0", "1 1", "0 1"] {
            obj += &format!("vt {uv}\n");
        }
        let b = 4 * k + 1;
        obj += &format!(
            "usemtl {m}\nf {}/{} {}/{} {}/{} {}/{}\n",
            b,
            b,
            b + 1,
            b + 1,
            b + 2,
            b + 2,
            b + 3,
            b + 3
        );
    }
    std::fs::write(dir.join("room.obj"), obj).unwrap();
    std::fs::write(
        dir.join("room.mtl"),
        "newmtl floor\nKd 0.8 0.8 0.8\nmap_Kd floor.png\n\nnewmtl wall\nKd 0.6 0.6 0.6\n",
    )
    .unwrap();
    std::fs::write(
        dir.join("room.json"),
        r#"{"camera": {"position": [1.0, 1.2, 2.3], "target": [1.0, 0.3, 0.5], "up": [0, 1, 0], "fov_y_deg": 60},
            "lights": [{"type": "point", "position": [1.0, 1.2, 1.2], "intensity": [2, 2, 2]}], "units": "m"}"#,
    )
    .unwrap();
    dir
}

/// Every file under `dir` with its bytes.
fn snapshot(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut out = BTreeMap::new();
    for e in walk(dir) {
        if let Ok(bytes) = std::fs::read(&e) {
            out.insert(e, bytes);
        }
    }
    out
}

fn walk(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).unwrap().flatten() {
        let p = e.path();
        if p.is_dir() {
            out.extend(walk(&p));
        } else {
            out.push(p);
        }
    }
    out
}

/// `args` is refused with exit 1, an error naming `flag` and `input`, and
/// leaves `dir` exactly as it was (no file changed, none added).
fn refused(dir: &Path, args: &[&str], flag: &str, input: &str) {
    let before = snapshot(dir);
    let o = radiosity(args);
    let err = stderr(&o);
    assert_eq!(
        o.status.code(),
        Some(1),
        "{args:?} should be refused:\n{err}"
    );
    assert!(
        err.contains(flag) && err.contains(input),
        "{args:?}: the error names {flag} and {input}:\n{err}"
    );
    assert!(
        !err.contains("[bake] voxelizing"),
        "{args:?}: refused only after work:\n{err}"
    );
    assert_eq!(snapshot(dir), before, "{args:?} changed the folder");
}

#[test]
fn no_output_may_be_an_input() {
    let dir = textured_room("outputs-inputs");
    let s = |name: &str| dir.join(name).to_str().unwrap().to_string();
    let (obj, mtl, tex, json) = (s("room.obj"), s("room.mtl"), s("floor.png"), s("room.json"));
    // A bake to render from (outside the folder, which the refusals must
    // leave as it is).
    let rad_dir = common::temp_dir("outputs-bake");
    let rad = rad_dir.join("room.rad");
    let o = radiosity(&[
        "bake",
        &obj,
        "--patches",
        "60",
        "--codec",
        "bc1",
        "--error-lights",
        "0",
        "-o",
        rad.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let rad = rad.to_str().unwrap();

    // bake: over the OBJ, the MTL, the texture; by another spelling, a
    // symbolic link and a hard link.
    refused(&dir, &["bake", &obj, "-o", &obj], "-o", "the scene");
    refused(&dir, &["bake", &obj, "-o", &mtl], "-o", "material library");
    refused(&dir, &["bake", &obj, "-o", &tex], "-o", "texture");
    let odd = format!(
        "{}/./../{}/room.mtl",
        s("."),
        dir.file_name().unwrap().to_str().unwrap()
    );
    refused(&dir, &["bake", &obj, "-o", &odd], "-o", "material library");
    let links = common::temp_dir("outputs-links");
    let sym = links.join("sym.rad");
    std::os::unix::fs::symlink(dir.join("room.obj"), &sym).unwrap();
    refused(
        &dir,
        &["bake", &obj, "-o", sym.to_str().unwrap()],
        "-o",
        "the scene",
    );
    let hard = links.join("hard.rad");
    std::fs::hard_link(dir.join("room.mtl"), &hard).unwrap();
    refused(
        &dir,
        &["bake", &obj, "-o", hard.to_str().unwrap()],
        "-o",
        "material library",
    );
    // --export writes patches.png: not over a texture of that name.
    let export_dir = common::temp_dir("outputs-export");
    std::fs::copy(dir.join("floor.png"), export_dir.join("patches.png")).unwrap();
    let mtl2 = export_dir.join("room.mtl");
    std::fs::write(
        &mtl2,
        "newmtl floor\nKd 0.8 0.8 0.8\nmap_Kd patches.png\n\nnewmtl wall\nKd 0.6 0.6 0.6\n",
    )
    .unwrap();
    std::fs::copy(dir.join("room.obj"), export_dir.join("room.obj")).unwrap();
    let obj2 = export_dir.join("room.obj");
    refused(
        &export_dir,
        &[
            "bake",
            obj2.to_str().unwrap(),
            "--export",
            export_dir.to_str().unwrap(),
        ],
        "--export",
        "texture",
    );

    // render: the bake names the scene; its texture is found after loading
    // the bake and still refused before anything is drawn.
    refused(&dir, &["render", rad, "-o", &tex], "-o", "texture");
    refused(&dir, &["render", &obj, "-o", &tex], "-o", "texture");
    refused(
        &dir,
        &["render", rad, "--camera-lights", &json, "-o", &mtl],
        "-o",
        ".mtl",
    );
    refused(
        &dir,
        &["render", rad, "-o", &s("x.png"), "--hdr", &json],
        "--hdr",
        "PFM",
    );
    // view: --headless-to over a texture, --save-to over the OBJ.
    refused(
        &dir,
        &["view", rad, "--headless-to", &tex],
        "--headless-to",
        "texture",
    );
    refused(
        &dir,
        &["view", rad, "--save-to", &obj],
        "--save-to",
        "the scene",
    );
    // export-mitsuba: a scene whose OBJ is where the export writes a mesh.
    let mdir = common::temp_dir("outputs-mitsuba");
    std::fs::create_dir_all(mdir.join("meshes")).unwrap();
    std::fs::copy(dir.join("room.obj"), mdir.join("meshes/m0.obj")).unwrap();
    std::fs::copy(dir.join("room.mtl"), mdir.join("meshes/room.mtl")).unwrap();
    std::fs::copy(dir.join("floor.png"), mdir.join("meshes/floor.png")).unwrap();
    let mobj = mdir.join("meshes/m0.obj");
    refused(
        &mdir,
        &[
            "export-mitsuba",
            mobj.to_str().unwrap(),
            "-o",
            mdir.to_str().unwrap(),
        ],
        "-o",
        "the scene",
    );
    // bench compression's report over the scene.
    refused(
        &dir,
        &["bench", "compression", &obj, "--patches", "60", "-o", &obj],
        "-o",
        "the scene",
    );
    // A render that may write does write, and the inputs stay.
    let before = snapshot(&dir);
    let out = rad_dir.join("ok.png");
    let o = radiosity(&[
        "render",
        rad,
        "-o",
        out.to_str().unwrap(),
        "--width",
        "32",
        "--height",
        "24",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(out.exists());
    assert_eq!(snapshot(&dir), before);
}

#[test]
fn image_formats_follow_the_name_and_folders_are_checked_first() {
    let dir = textured_room("outputs-formats");
    let obj = dir.join("room.obj");
    let obj = obj.to_str().unwrap();
    let out = common::temp_dir("outputs-formats-out");
    let rad = out.join("room.rad");
    let o = radiosity(&[
        "bake",
        obj,
        "--patches",
        "60",
        "--codec",
        "bc1",
        "--error-lights",
        "0",
        "-o",
        rad.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let rad = rad.to_str().unwrap();
    let small = ["--width", "32", "--height", "24"];
    // .jpg is JPEG, .png PNG; other names are refused before rendering.
    for (name, magic) in [
        ("a.jpg", &[0xffu8, 0xd8][..]),
        ("b.JPEG", &[0xff, 0xd8]),
        ("c.png", &[0x89, b'P', b'N', b'G']),
    ] {
        let p = out.join(name);
        let mut args = vec!["render", rad, "-o", p.to_str().unwrap()];
        args.extend(small);
        let o = radiosity(&args);
        assert!(o.status.success(), "{name}: {}", stderr(&o));
        let bytes = std::fs::read(&p).unwrap();
        assert!(
            bytes.starts_with(magic),
            "{name} starts with {:?}",
            &bytes[..4]
        );
    }
    for name in ["d.bmp", "e", "f.rad"] {
        let p = out.join(name);
        let mut args = vec!["render", rad, "-o", p.to_str().unwrap()];
        args.extend(small);
        let o = radiosity(&args);
        assert_eq!(o.status.code(), Some(1), "{name}: {}", stderr(&o));
        assert!(
            stderr(&o).contains("expected .png, .jpg or .jpeg"),
            "{}",
            stderr(&o)
        );
        assert!(!p.exists());
    }
    // A missing folder is made (view's headless image too).
    let deep = out.join("new/deeper/v.png");
    let mut args = vec!["view", rad, "--headless-to", deep.to_str().unwrap()];
    args.extend(small);
    let o = radiosity(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(deep.exists());
    // A folder that cannot be made (a file stands in the way) stops the
    // bake before it starts.
    let blocked = dir.join("room.obj").join("x.rad");
    let t = std::time::Instant::now();
    let o = radiosity(&[
        "bake",
        obj,
        "--patches",
        "60",
        "-o",
        blocked.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("cannot create the folder"),
        "{}",
        stderr(&o)
    );
    assert!(!stderr(&o).contains("[bake] voxelizing"), "{}", stderr(&o));
    assert!(t.elapsed().as_secs_f64() < 10.0);
    // An output that names a folder.
    let o = radiosity(&["bake", obj, "--patches", "60", "-o", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("is a folder"), "{}", stderr(&o));
}

#[test]
fn the_benches_write_no_committed_report_unless_named() {
    for (sub, default) in [("sweep", "out/sweep"), ("skips", "out/skips")] {
        let o = radiosity(&["bench", sub, "--help"]);
        assert!(o.status.success());
        let help = String::from_utf8_lossy(&o.stdout);
        assert!(
            help.contains(&format!("[default: {default}]")),
            "bench {sub}: {help}"
        );
    }
}
