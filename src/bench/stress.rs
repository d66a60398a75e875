//! `radiosity bench stress`: numerical stability of the whole bake and
//! frame on scenes that are not kind (issue 14), generated here
//! ([`crate::generate::STRESS`], made by [`crate::generate::build`]) and transformed:
//!
//! - **scale**: the furnace box and the untessellated Cornell box at
//!   1e-3, 1 and 1e4 times their size (point and spot intensities scaled
//!   by the square so the irradiance stays the same, coordinates written
//!   with enough decimals for the size);
//! - **albedo**: the furnace at albedo 0.9 and at the loader's bound 0.99
//!   ([`crate::core::scene::ALBEDO_MAX`]; `bench transfer` takes the
//!   transfer alone to 0.999), where `H = E / (1 − ρ)` is known exactly;
//! - **small next to large, near-coincident surfaces**: the Cornell box
//!   with a light panel 1 cm below the ceiling and blocks standing on the
//!   floor; two rooms sharing a wall thinner than a voxel, one dark (its
//!   `H` must stay near 0).
//!
//! For each: the patches' `H` against the exact f64 product of the same
//! `F` (what the transfer and codec add), the furnace's mean and worst
//! relative error against `E / (1 − ρ)` (what the form factors add), the
//! dark room's largest `H` against the lit room's mean, the range of `H`,
//! and any non-finite value (there must be none: the run fails). Last,
//! the memory limit: the largest default bake that fits this machine, and
//! a bake asked for twice that refused before anything is allocated.

use super::frame::{exact_infinite, in_matrix_order, rel_rms};
use crate::bake::voxelize::Resolution;
use crate::bake::{self, BakeConfig, ComputeChoice};
use crate::bakefile::baked::Baked;
use crate::core::compute::DeviceSelection;
use crate::core::scene;
use crate::core::scene_config::Light;
use crate::generate::{self, GeneratedScene};
use crate::runtime::{Runtime, RuntimeOptions};
use anyhow::Context;
use std::fmt::Write as _;
use std::path::Path;

/// One case: a generated scene, transformed.
pub struct StressCase {
    pub name: String,
    pub scene: GeneratedScene,
    /// `E / (1 − ρ)` where the scene is a closed furnace.
    pub furnace: Option<f64>,
    /// Two rooms: patches whose centre has x above this are the dark room.
    pub dark_room_x: Option<f64>,
}

/// `g` scaled by `s` (module doc).
fn scaled(mut g: GeneratedScene, s: f64) -> GeneratedScene {
    for p in &mut g.mesh.positions {
        *p = p.map(|v| v * s);
    }
    // Enough decimals that the coordinates keep 5 significant places
    // below the unit scale.
    if s < 1.0 {
        g.decimals += (-s.log10()).ceil() as usize;
    }
    let sf = s as f32;
    let c = &mut g.config.camera;
    c.position = c.position.map(|v| v * sf);
    c.target = c.target.map(|v| v * sf);
    for l in &mut g.config.lights {
        match l {
            Light::Point {
                position,
                intensity,
            }
            | Light::Spot {
                position,
                intensity,
                ..
            } => {
                *position = position.map(|v| v * sf);
                *intensity = intensity.map(|v| v * sf * sf);
            }
            Light::Directional { .. } => {}
        }
    }
    g.name = format!("{}_x{s:e}", g.name);
    g
}

/// The cases of the module doc.
pub fn cases() -> anyhow::Result<Vec<StressCase>> {
    let mut out = Vec::new();
    let furnace = generate::build("odd_box")?;
    let rho = furnace.materials[0].kd[0] as f64;
    let e = furnace.materials[0].ke[0] as f64;
    for s in [1e-3, 1.0, 1e4] {
        out.push(StressCase {
            name: format!("furnace ρ {rho:.2}, scale {s:e}"),
            scene: scaled(furnace.clone(), s),
            furnace: Some(e / (1.0 - rho)),
            dark_room_x: None,
        });
    }
    let mut bright = furnace.clone();
    let high = crate::core::scene::ALBEDO_MAX;
    bright.materials[0].kd = [high; 3];
    bright.name = "odd_box_099".into();
    out.push(StressCase {
        name: format!("furnace ρ {high}"),
        scene: bright,
        furnace: Some(e / (1.0 - high as f64)),
        dark_room_x: None,
    });
    let published = generate::build("cornell_published")?;
    for s in [1e-3, 1.0, 1e4] {
        out.push(StressCase {
            name: format!("Cornell box, untessellated, scale {s:e} (mm)"),
            scene: scaled(published.clone(), s),
            furnace: None,
            dark_room_x: None,
        });
    }
    out.push(StressCase {
        name: "Cornell box, panel 1 cm below the ceiling".into(),
        scene: generate::build("cornell_panel")?,
        furnace: None,
        dark_room_x: None,
    });
    out.push(StressCase {
        name: "two rooms, 2 cm wall, right room dark".into(),
        scene: generate::build("two_rooms")?,
        furnace: None,
        dark_room_x: Some(2.02),
    });
    Ok(out)
}

/// One case's measures.
#[derive(Clone, Debug)]
pub struct StressRow {
    pub name: String,
    pub patches: usize,
    pub h_error: f64,
    pub furnace_mean: Option<f64>,
    pub furnace_worst: Option<f64>,
    pub dark_over_lit: Option<f64>,
    pub h_min: f64,
    pub h_max: f64,
    pub non_finite: usize,
    pub seconds: f64,
}

fn run_case(
    c: &StressCase,
    dir: &Path,
    patches: usize,
    selection: DeviceSelection,
) -> anyhow::Result<StressRow> {
    let start = std::time::Instant::now();
    let files = c.scene.write(dir)?;
    let obj = files
        .iter()
        .find(|p| p.extension().is_some_and(|e| e == "obj"))
        .context("the generator wrote no OBJ")?
        .clone();
    let mut cfg = BakeConfig::new(obj.clone(), Resolution::Patches(patches));
    cfg.compute = ComputeChoice::OpenCl(selection);
    let output = bake::run(&cfg, &mut |_| {})?;
    let baked = Baked::from_file(&output.file, &c.scene.name)?;
    let n = baked.patches.len();
    let order = output.permutation.order.clone();
    let ff = &output.form_factors;
    let f = in_matrix_order(&ff.f, n, &order);
    let albedo: Vec<[f32; 3]> = baked.patches.iter().map(|p| p.albedo).collect();
    let centres: Vec<[f32; 3]> = baked.patches.iter().map(|p| p.centre).collect();
    let areas: Vec<f64> = baked.patches.iter().map(|p| p.area as f64).collect();
    let mut rt = Runtime::new(baked, scene::load(&obj)?, RuntimeOptions::default());
    let config = &c.scene.config;
    rt.frame(&config.lights, &config.emission);
    // The compressed gather alone (without the near-field correction),
    // against the exact T B0 of the same F.
    let b0 = rt.b0().clone();
    let (h, _, _) = rt.product(&b0);
    let exact = exact_infinite(&f, n, &albedo, &b0);
    let non_finite = h
        .iter()
        .chain(&b0)
        .flatten()
        .filter(|v| !v.is_finite())
        .count()
        + exact.iter().flatten().filter(|v| !v.is_finite()).count();
    let g = &h[1];
    let (h_min, h_max) = g.iter().fold((f64::MAX, f64::MIN), |(a, b), &v| {
        (a.min(v as f64), b.max(v as f64))
    });
    let (furnace_mean, furnace_worst) = match c.furnace {
        Some(want) => {
            let total: f64 = areas.iter().sum();
            let mean = g
                .iter()
                .zip(&areas)
                .map(|(&v, a)| v as f64 * a)
                .sum::<f64>()
                / total;
            let worst = g
                .iter()
                .map(|&v| ((v as f64 - want) / want).abs())
                .fold(0.0, f64::max);
            (Some(mean / want - 1.0), Some(worst))
        }
        None => (None, None),
    };
    let dark_over_lit = c.dark_room_x.map(|x| {
        let (mut dark, mut lit, mut k) = (0.0f64, 0.0f64, 0usize);
        for (j, p) in centres.iter().enumerate() {
            if p[0] as f64 > x {
                dark = dark.max(g[j] as f64);
            } else {
                lit += g[j] as f64;
                k += 1;
            }
        }
        dark / (lit / k.max(1) as f64).max(1e-300)
    });
    Ok(StressRow {
        name: c.name.clone(),
        patches: n,
        h_error: rel_rms(&h, &exact),
        furnace_mean,
        furnace_worst,
        dark_over_lit,
        h_min,
        h_max,
        non_finite,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// Runs every case at `patches`; returns the Markdown table, or an error
/// (after printing it) when any value is non-finite.
pub fn run(
    patches: usize,
    selection: DeviceSelection,
    progress: &mut dyn FnMut(&str),
) -> anyhow::Result<String> {
    let root = std::env::temp_dir().join(format!("radiosity-stress-{}", std::process::id()));
    let mut rows = Vec::new();
    for (k, c) in cases()?.iter().enumerate() {
        progress(&c.name);
        let dir = root.join(format!("{k}"));
        let row = run_case(c, &dir, patches, selection).with_context(|| c.name.clone())?;
        rows.push(row);
    }
    let limit = memory_limit(&root, selection)?;
    progress(&limit);
    let _ = std::fs::remove_dir_all(&root);
    let mut s = String::new();
    let _ = writeln!(
        s,
        "| case | patches | H error vs f64 exact (same F) | furnace: mean / worst vs E/(1−ρ) | dark room max H / lit mean | H range (green) | non-finite | time |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|");
    let pct = |v: Option<f64>| v.map_or("—".into(), |x| format!("{:+.2} %", 100.0 * x));
    for r in &rows {
        let _ = writeln!(
            s,
            "| {} | {} | {:.3} % | {} / {} | {} | {:.3e} … {:.3e} | {} | {:.1} s |",
            r.name,
            r.patches,
            100.0 * r.h_error,
            pct(r.furnace_mean),
            r.furnace_worst
                .map_or("—".into(), |x| format!("{:.2} %", 100.0 * x)),
            r.dark_over_lit.map_or("—".into(), |x| format!("{x:.2e}")),
            r.h_min,
            r.h_max,
            r.non_finite,
            r.seconds
        );
    }
    let _ = writeln!(s, "\n{limit}");
    let bad: Vec<&StressRow> = rows.iter().filter(|r| r.non_finite > 0).collect();
    if !bad.is_empty() {
        anyhow::bail!(
            "{s}\nnon-finite values in: {}",
            bad.iter()
                .map(|r| r.name.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    Ok(s)
}

/// The memory limit of this machine for a default bake: the largest patch
/// count that fits (`bake::budget`), and a bake asked for twice that (or
/// past the file format's limit) refused before anything is voxelized or
/// allocated, with a message that names the limit. Running at the limit
/// itself takes hours on a CPU device; this checks that going past it is
/// a clear error, never an abort.
fn memory_limit(root: &std::path::Path, selection: DeviceSelection) -> anyhow::Result<String> {
    use crate::bake::budget;
    let gpu = crate::core::compute::Gpu::new(selection)?;
    let device = budget::Device::OpenCl {
        info: gpu.info(),
        matrices: crate::bake::transfer::cl_matrices(&Default::default()),
    };
    let available = budget::host_available();
    let largest = available.map(|a| budget::largest_fitting(a, device, false));
    drop(gpu);
    let ask = largest.map_or(budget::MAX_PATCHES_FORMAT + 1, |l| {
        (2 * l.max(1)).min(budget::MAX_PATCHES_FORMAT + 1)
    });
    std::fs::create_dir_all(root)?;
    let obj = root.join("limit.obj");
    std::fs::write(
        &obj,
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n",
    )?;
    let mut cfg = BakeConfig::new(obj, Resolution::Patches(ask));
    cfg.compute = ComputeChoice::OpenCl(selection);
    let start = std::time::Instant::now();
    let refused = match bake::run(&cfg, &mut |_| {}) {
        Ok(_) => anyhow::bail!("a bake of {ask} patches, past the memory limit, was not refused"),
        Err(e) => format!("{e:#}"),
    };
    Ok(format!(
        "Memory limit: host memory available {}, largest default bake that fits about {} patches; a bake of {ask} patches is refused in {:.2} s, before voxelizing: \"{refused}\"",
        available.map_or("unknown".into(), |a| format!("{:.1} GB", a as f64 / 1e9)),
        largest.map_or("unknown".into(), |l| l.to_string()),
        start.elapsed().as_secs_f64()
    ))
}
