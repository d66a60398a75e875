//! The crates enforce the two phases (`docs/architecture.md`): the run time
//! and the renderer depend on the core and the bake file only, never on a
//! bake stage, and the run-time crate a renderer embeds pulls in no
//! OpenCL, no windowing, no GL context library and no texture encoder.
//! Read from `cargo tree`, the dependency graph cargo itself builds.

use std::collections::BTreeSet;
use std::process::Command;

/// The names of every package `package` depends on for its build (normal
/// edges, transitively), from `cargo tree`.
fn dependencies(package: &str) -> BTreeSet<String> {
    let out = Command::new(env!("CARGO"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args([
            "tree",
            "-p",
            package,
            "-e",
            "normal",
            "--prefix",
            "none",
            "--offline",
        ])
        .output()
        .expect("running cargo tree");
    assert!(
        out.status.success(),
        "cargo tree -p {package}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .skip(1)
        .filter_map(|l| l.split_whitespace().next().map(str::to_string))
        .collect()
}

/// Packages that must not be under the run time: OpenCL, the window and
/// its GL context, the BC1 encoder, and the bake itself.
const NOT_IN_THE_RUN_TIME: [&str; 7] = [
    "opencl3",
    "cl3",
    "winit",
    "glutin",
    "glutin-winit",
    "intel_tex_2",
    "radiosity-bake",
];

#[test]
fn the_run_time_crate_needs_no_opencl_window_gl_context_or_encoder() {
    let deps = dependencies("radiosity-runtime");
    assert!(
        deps.contains("radiosity-core") && deps.contains("radiosity-bakefile"),
        "{deps:?}"
    );
    for bad in NOT_IN_THE_RUN_TIME.iter().chain(&["glow", "radiosity-gl"]) {
        assert!(!deps.contains(*bad), "radiosity-runtime depends on {bad}");
    }
}

#[test]
fn the_renderer_depends_on_the_core_the_contract_and_the_cpu_run_time_only() {
    let deps = dependencies("radiosity-gl");
    for bad in [
        "opencl3",
        "cl3",
        "winit",
        "glutin-winit",
        "intel_tex_2",
        "radiosity-bake",
    ] {
        assert!(!deps.contains(bad), "radiosity-gl depends on {bad}");
    }
    assert!(deps.contains("radiosity-runtime") && deps.contains("glow"));
}

#[test]
fn the_core_and_the_contract_depend_on_no_phase() {
    for package in ["radiosity-core", "radiosity-bakefile"] {
        let deps = dependencies(package);
        for bad in NOT_IN_THE_RUN_TIME
            .iter()
            .chain(&["glow", "radiosity-gl", "radiosity-runtime"])
        {
            assert!(!deps.contains(*bad), "{package} depends on {bad}");
        }
    }
    // The bake never imports the run time.
    let bake = dependencies("radiosity-bake");
    for bad in [
        "radiosity-runtime",
        "radiosity-gl",
        "glow",
        "winit",
        "glutin",
    ] {
        assert!(!bake.contains(bad), "radiosity-bake depends on {bad}");
    }
}
