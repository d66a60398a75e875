//! `radiosity bench probes`: the probes' irradiance against Mitsuba 3's
//! irradiance meter at the probes (issue 46, `docs/probes.md`). For an
//! evenly spread subset of the valid probes of a bake, after one frame of
//! the camera-and-lights file's lights and sky, each probe's band-2
//! irradiance about the six axis directions is compared with
//! `scripts/mitsuba/irradiance.py` on the Mitsuba export of the same scene
//! (the run time's scene, back sides included), at the same points and
//! normals: the light arriving from surfaces, area emitters and the sky,
//! without the delta lights' direct light, which is what the probes hold.
//! Mitsuba's noise is known from two independent halves and removed from
//! the error (as `src/mitsuba/reference.rs` does for images). Our path
//! tracer (`crate::reference`) at the same points is reported beside it.

use crate::core::scene_config::SceneConfig;
use crate::runtime::probes::irradiance;
use crate::runtime::{Runtime, RuntimeOptions};
use anyhow::{bail, Context};
use std::fmt::Write as _;
use std::path::Path;
use std::process::Command;

/// The six normals each probe is compared about: ±x, ±y, ±z.
pub const AXES: [[f64; 3]; 6] = [
    [1.0, 0.0, 0.0],
    [-1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.0, -1.0, 0.0],
    [0.0, 0.0, 1.0],
    [0.0, 0.0, -1.0],
];

/// The benchmark's options.
#[derive(Clone, Debug)]
pub struct ProbeBenchOptions {
    /// Probes compared (evenly spread over the valid ones).
    pub probes: usize,
    /// Mitsuba paths per point and normal (both halves).
    pub spp: usize,
    /// Our path tracer's paths per point and normal (0: not run).
    pub paths: usize,
}

/// One comparison's figures.
#[derive(Clone, Debug, Default)]
pub struct ProbeComparison {
    pub probes: usize,
    /// Relative RMS of the probes against Mitsuba's mean, and with its
    /// noise removed; the noise; the bias (relative mean difference).
    pub raw: f64,
    pub error: f64,
    pub noise: f64,
    pub bias: f64,
    /// Relative RMS of our path tracer against Mitsuba (noise of both in
    /// it), when run.
    pub path_tracer: Option<f64>,
}

/// Runs the comparison on the bake at `path` with `config`; returns the
/// Markdown report and the figures.
pub fn run(
    path: &Path,
    config: &SceneConfig,
    options: &ProbeBenchOptions,
) -> anyhow::Result<(String, ProbeComparison)> {
    let (baked, scene, _) = crate::runtime::open::load_checked(path, None)?;
    if baked.probes.is_empty() {
        bail!(
            "{} has no irradiance probes (baked with --probe-spacing 0, or before probes existed)",
            path.display()
        );
    }
    let two_sided = baked.options.two_sided;
    let mut rt = Runtime::new(baked, scene, RuntimeOptions::default());
    rt.set_sky(config.sky.clone())
        .context("the camera-and-lights file's sky")?;
    let lights = config.frame_lights();
    rt.frame(&lights, &config.emission);
    let probes = &rt.baked.probes;
    let valid: Vec<usize> = (0..probes.len())
        .filter(|&p| probes.states[p].is_used())
        .collect();
    if valid.is_empty() {
        bail!("{}: every probe is in a solid", path.display());
    }
    let k = options.probes.clamp(1, valid.len());
    let chosen: Vec<usize> = (0..k).map(|i| valid[i * valid.len() / k]).collect();

    // The Mitsuba export and the meter.
    let dir = std::env::temp_dir().join(format!("radiosity-probes-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir)?;
    crate::mitsuba::export(
        &rt.scene,
        config,
        crate::mitsuba::ExportOptions {
            width: 1,
            height: 1,
            two_sided,
        },
        &dir.join("scene"),
    )?;
    let mut points = String::from("[");
    for (i, &p) in chosen.iter().enumerate() {
        let x = probes.grid.position(p);
        for (a, n) in AXES.iter().enumerate() {
            if i + a > 0 {
                points.push(',');
            }
            write!(
                points,
                "{{\"position\":[{:?},{:?},{:?}],\"normal\":[{:?},{:?},{:?}]}}",
                x[0], x[1], x[2], n[0], n[1], n[2]
            )?;
        }
    }
    points.push(']');
    std::fs::write(dir.join("points.json"), points)?;
    let cache = std::env::var_os("RADIOSITY_CACHE_DIR")
        .map(std::path::PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| Path::new(&h).join(".cache/radiosity")))
        .context("no cache directory (set RADIOSITY_CACHE_DIR)")?;
    let python = cache.join("mitsuba-venv/bin/python");
    if !python.exists() {
        bail!(
            "no Mitsuba environment at {}: run scripts/mitsuba-reference once (it installs it)",
            python.display()
        );
    }
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/mitsuba/irradiance.py");
    let (lo, hi) = rt.scene.bounds();
    let extent = (0..3).map(|a| f64::from(hi[a] - lo[a])).fold(0.0, f64::max);
    let t0 = std::time::Instant::now();
    let status = Command::new(&python)
        .arg(&script)
        .arg(dir.join("scene"))
        .arg(dir.join("points.json"))
        .arg("--out")
        .arg(dir.join("meter.json"))
        .arg("--spp")
        .arg(options.spp.to_string())
        .arg("--size")
        .arg(format!("{:e}", 1e-4 * extent))
        .status()
        .with_context(|| format!("running {}", script.display()))?;
    if !status.success() {
        bail!("{} failed ({status})", script.display());
    }
    let t_mitsuba = t0.elapsed().as_secs_f64();
    let meter: Vec<serde_json::Value> =
        serde_json::from_str(&std::fs::read_to_string(dir.join("meter.json"))?)?;
    let _ = std::fs::remove_dir_all(&dir);
    let rgb = |v: &serde_json::Value| -> [f64; 3] {
        std::array::from_fn(|c| v[c].as_f64().unwrap_or(f64::NAN))
    };
    let sh = rt.probe_sh();
    let (mut num, mut den, mut noise2, mut sum_d, mut sum_m) = (0.0, 0.0, 0.0, 0.0, 0.0);
    let mut ours = Vec::new();
    let mut means = Vec::new();
    for (i, &p) in chosen.iter().enumerate() {
        for (a, n) in AXES.iter().enumerate() {
            let m = &meter[6 * i + a];
            let (ma, mb) = (rgb(&m["a"]), rgb(&m["b"]));
            let e = irradiance(&sh[p], n.map(|v| v as f32));
            for c in 0..3 {
                let mean = 0.5 * (ma[c] + mb[c]);
                let d = f64::from(e[c]) - mean;
                num += d * d;
                den += mean * mean;
                noise2 += (0.5 * (ma[c] - mb[c])).powi(2);
                sum_d += d;
                sum_m += mean;
            }
            ours.push(e);
            means.push(std::array::from_fn::<f64, 3, _>(|c| 0.5 * (ma[c] + mb[c])));
        }
    }
    if !(den > 0.0 && num.is_finite()) {
        bail!("the meter read no light at the chosen probes (is the scene lit?)");
    }
    // The largest squared differences, for the report.
    let mut worst: Vec<(f64, usize, usize)> = Vec::new();
    for (i, _) in chosen.iter().enumerate() {
        for a in 0..6 {
            let e = ours[6 * i + a];
            let m = means[6 * i + a];
            let d2: f64 = (0..3).map(|c| (f64::from(e[c]) - m[c]).powi(2)).sum();
            worst.push((d2, i, a));
        }
    }
    worst.sort_by(|x, y| y.0.total_cmp(&x.0));
    let raw = (num / den).sqrt();
    let noise = (noise2 / den).sqrt();
    let error = ((num - noise2).max(0.0) / den).sqrt();
    let bias = sum_d / sum_m;
    let path_tracer = (options.paths > 0).then(|| {
        let pt = crate::reference::PathTracer::new(&rt.scene).with_sky(config.sky.clone());
        let (mut num, mut den) = (0.0, 0.0);
        for (i, &p) in chosen.iter().enumerate() {
            let x = probes.grid.position(p);
            for (a, n) in AXES.iter().enumerate() {
                let (h, s) =
                    pt.indirect_and_sky(x, *n, &lights, options.paths, None, (6 * i + a) as u64);
                for ((hm, sm), m) in h.mean.iter().zip(&s.mean).zip(&means[6 * i + a]) {
                    let d = hm + sm - m;
                    num += d * d;
                    den += m * m;
                }
            }
        }
        (num / den).sqrt()
    });
    let figures = ProbeComparison {
        probes: k,
        raw,
        error,
        noise,
        bias,
        path_tracer,
    };
    let mut out = String::new();
    writeln!(
        out,
        "## {}: {} probes of {} used ({} in all), {} rays each, {} patches\n",
        path.display(),
        k,
        valid.len(),
        probes.len(),
        probes.rays,
        rt.n()
    )?;
    writeln!(out, "| measure | value |")?;
    writeln!(out, "|---|---|")?;
    writeln!(
        out,
        "| probes' irradiance about ±x, ±y, ±z against Mitsuba 3's irradiance meter (scalar_rgb, ∞ bounces, {} paths each; {:.1} s) | **{:.2} %** relative RMS with the meter's noise removed ({:.2} % raw; the meter's noise {:.2} %); bias {:+.2} % |",
        options.spp,
        t_mitsuba,
        100.0 * error,
        100.0 * raw,
        100.0 * noise,
        100.0 * bias
    )?;
    if let Some(e) = path_tracer {
        writeln!(
            out,
            "| our path tracer at the same points and normals ({} paths) against the meter | {:.2} % relative RMS (both noises in it) |",
            options.paths,
            100.0 * e
        )?;
    }
    writeln!(
        out,
        "\nThe largest differences (their share of the squared error):\n"
    )?;
    writeln!(
        out,
        "| probe | position | normal | probes | meter | share |"
    )?;
    writeln!(out, "|---|---|---|---|---|---|")?;
    for &(d2, i, a) in worst.iter().take(5) {
        let x = probes.grid.position(chosen[i]);
        let m = means[6 * i + a];
        let e = ours[6 * i + a];
        writeln!(
            out,
            "| {} | [{:.3}, {:.3}, {:.3}] | {:?} | [{:.4}, {:.4}, {:.4}] | [{:.4}, {:.4}, {:.4}] | {:.1} % |",
            chosen[i],
            x[0],
            x[1],
            x[2],
            AXES[a],
            e[0],
            e[1],
            e[2],
            m[0],
            m[1],
            m[2],
            100.0 * d2 / num
        )?;
    }
    Ok((out, figures))
}
