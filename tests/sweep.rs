//! `radiosity bench sweep --quick`, the one benchmark in CI: it must run
//! (OpenCL on PoCL, GL on llvmpipe), write its JSON, Markdown and plots,
//! and pass its own checks (every value finite, every baseline point's
//! error within the bound, and its indirect image against Mitsuba 3 within
//! 15 %). Timings are printed by the sweep, never asserted here. The
//! Mitsuba environment and reference are cached in this build's temporary
//! directory, shared with tests/mitsuba.rs.

mod common;

use std::process::Command;

#[test]
fn the_quick_sweep_runs_writes_its_report_and_passes_its_checks() {
    common::gpu();
    let dir = common::temp_dir("sweep-quick");
    let o = Command::new(env!("CARGO_BIN_EXE_radiosity"))
        .args(["bench", "sweep", "--quick", "-o"])
        .arg(&dir)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env(
            "RADIOSITY_CACHE_DIR",
            std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("radiosity-cache"),
        )
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    eprintln!("{err}");
    assert!(o.status.success(), "the quick sweep failed: {err}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("sweep.json")).unwrap()).unwrap();
    let points = json.as_array().unwrap();
    // 2 patch counts × (baseline, 2 bounce counts, 1 codec, 1 reordering).
    assert_eq!(points.len(), 10);
    for p in points {
        assert_eq!(p["all_finite"], true);
        let e = p["h_error"].as_f64().unwrap();
        assert!(e.is_finite() && e >= 0.0);
        assert!(p["bytes_per_entry"].as_f64().unwrap() > 0.0);
        assert!(p["classic_ms"].as_f64().unwrap() > 0.0);
        if p["varied"] == "baseline" {
            assert!(e <= 0.05, "baseline error {e}");
            assert!(p["classic_inf_passes"].as_u64().unwrap() >= 3);
        }
        // The images were measured against Mitsuba 3; the baseline's within
        // the quick sweep's bound (about 10 % at 256 patches, 4 % at 600).
        let img = &p["image_indirect"];
        let ie = img["rel_rms"].as_f64().unwrap();
        assert!(
            ie.is_finite() && img["noise"].as_f64().unwrap() > 0.0,
            "{img}"
        );
        if p["varied"] == "baseline" {
            assert!(ie <= 0.15, "baseline indirect image error {ie}");
        }
        // GL ran on llvmpipe: the frame's passes were timed.
        assert!(p["gl_frame_ms"].as_f64().is_some(), "no GL frame: {p}");
    }
    let md = std::fs::read_to_string(dir.join("sweep.md")).unwrap();
    assert!(md.contains("| cornell_box |"));
    assert!(md.contains("reference noise per pixel"));
    for svg in ["pareto_time.svg", "pareto_bytes.svg", "pareto_image.svg"] {
        let s = std::fs::read_to_string(dir.join(svg)).unwrap();
        assert!(s.matches("<circle").count() >= 10, "{svg}");
    }
}
