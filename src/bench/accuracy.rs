//! `radiosity bench accuracy`: a bake's patch irradiance against an
//! independent reference (docs/design.md section 3, measure 4): the Monte Carlo
//! path tracer of [`crate::reference`] on the original triangles.
//!
//! For every patch, the reference is the mean indirect irradiance over the
//! patch's sample points on its real surface. The bake's `H = T̃ · B0` uses
//! `B0 = ρ ∘ D + E` with `D` the mean direct irradiance over the same
//! points with the same shadow rays — the path tracer's own direct light —
//! so that only the transfer is judged (voxel simplification, form
//! factors, bounces, codec). Reported: the bias (area-weighted `Σ A H / Σ A
//! H_ref − 1`), the relative RMS error over patches, area-weighted
//! (`√(Σ A (H − H_ref)²) / √(Σ A H_ref²)`), the reference's own noise in
//! the same measure, and the same for the first reflection (`F · B0`
//! against one reflection, `F` recomputed from the bake's options) and for
//! the later bounces (the difference). Under a sky (the camera-and-lights
//! file's), `H` carries the sky bounced, and the sky's direct irradiance
//! on the patches (`D_sky`, from the baked sky cells) is compared with the
//! path tracer's, which sees the sky where its first direction leaves the
//! scene. Also the form factors' area-weighted
//! row sums against the fraction of the real hemisphere that meets front
//! faces, measured by cosine-distributed rays from the same points.

use crate::bake::form_factor::{of_voxelization, FormFactorOptions};
use crate::bake::voxelize::voxelize_at;
use crate::bakefile::baked::{resolve_scene_path, Baked};
use crate::bakefile::surface::SAMPLES_PER_PATCH;
use crate::core::compute::{Backend, DeviceSelection, Gpu};
use crate::core::scene;
use crate::core::scene_config::SceneConfig;
use crate::reference::PathTracer;
use crate::runtime::near_field::NearTerms;
use crate::runtime::{direct, Runtime, RuntimeOptions};
use anyhow::Context as _;
use rayon::prelude::*;
use serde::Serialize;
use std::fmt::Write as _;
use std::path::Path;

/// One comparison: bias, relative RMS, and the reference's noise.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct Comparison {
    pub bias: f64,
    pub rel_rms: f64,
    pub noise: f64,
}

/// What [`run`] measured.
#[derive(Clone, Debug, Default, Serialize)]
pub struct AccuracyReport {
    pub patches: usize,
    pub paths_per_point: usize,
    pub points_per_patch: usize,
    pub total: Comparison,
    pub first_reflection: Option<Comparison>,
    pub later_bounces: Option<Comparison>,
    /// The sky's direct irradiance `D_sky` against the path tracer's.
    pub sky: Option<Comparison>,
    /// Area-weighted mean row sum of `F`, and of the front-face fraction.
    pub row_sum: Option<f64>,
    pub front_fraction: f64,
    pub seconds_reference: f64,
}

/// Compares per-patch values (three channels pooled, area-weighted).
pub fn compare(areas: &[f64], h: &[[f64; 3]], r: &[[f64; 3]], se: &[[f64; 3]]) -> Comparison {
    let (mut sh, mut sr, mut d2, mut r2, mut n2) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for (j, &a) in areas.iter().enumerate() {
        for c in 0..3 {
            sh += a * h[j][c];
            sr += a * r[j][c];
            d2 += a * (h[j][c] - r[j][c]).powi(2);
            r2 += a * r[j][c] * r[j][c];
            n2 += a * se[j][c] * se[j][c];
        }
    }
    let ratio = |x: f64, y: f64| if y > 0.0 { x / y } else { 0.0 };
    Comparison {
        bias: ratio(sh, sr) - 1.0,
        rel_rms: ratio(d2.sqrt(), r2.sqrt()),
        noise: ratio(n2.sqrt(), r2.sqrt()),
    }
}

/// Runs the comparison for the bake at `path` lit by `config`, `paths`
/// paths from each of `points` sample points per patch; `first` also
/// measures the first reflection through a recomputed `F` on `selection`;
/// `per_patch` writes one CSV row per patch (see `write_per_patch`);
/// `near_field` applies the bake's near-field correction (off: to measure
/// what it does).
pub fn run(
    path: &Path,
    config: &SceneConfig,
    paths: usize,
    points: usize,
    first: Option<DeviceSelection>,
    per_patch: Option<&Path>,
    near_field: bool,
) -> anyhow::Result<(AccuracyReport, String)> {
    let baked = Baked::load(path)?;
    let scene_path = resolve_scene_path(path, &baked.info.scene);
    let scene = scene::load(&scene_path)
        .with_context(|| format!("loading the scene {}", scene_path.display()))?;
    let n = baked.patches.len();
    let points = points.clamp(1, SAMPLES_PER_PATCH);
    let mut rt = Runtime::new(
        baked,
        scene,
        RuntimeOptions {
            samples: points,
            near_field,
            ..RuntimeOptions::default()
        },
    );
    rt.set_sky(config.sky.clone())
        .context("the camera-and-lights file has a sky")?;
    // The file's lights and the sky's sun.
    let lights = &config.frame_lights()[..];
    rt.frame(lights, &config.emission);
    let areas: Vec<f64> = rt.baked.patches.iter().map(|p| p.area as f64).collect();
    let groups: Vec<Vec<([f64; 3], [f64; 3])>> = (0..n)
        .map(|j| {
            (0..points)
                .map(|k| {
                    let i = j * SAMPLES_PER_PATCH + k;
                    (
                        rt.baked.samples.position[i].map(f64::from),
                        rt.baked.samples.normal[i].map(f64::from),
                    )
                })
                .collect()
        })
        .collect();
    let start = std::time::Instant::now();
    let pt = PathTracer::new(&rt.scene).with_sky(config.sky.clone());
    let (reference, sky_reference): (Vec<_>, Vec<_>) = pt
        .mean_over_with_sky(&groups, lights, paths, None, 0x5eed)
        .into_iter()
        .unzip();
    let h: Vec<[f64; 3]> = (0..n)
        .map(|j| std::array::from_fn(|c| rt.h()[c][j] as f64))
        .collect();
    let r: Vec<[f64; 3]> = reference.iter().map(|e| e.mean).collect();
    let se: Vec<[f64; 3]> = reference.iter().map(|e| e.std_error).collect();
    if let Some(out) = per_patch {
        write_per_patch(out, &rt, &h, &r, &se)?;
    }
    let mut report = AccuracyReport {
        patches: n,
        paths_per_point: paths,
        points_per_patch: points,
        total: compare(&areas, &h, &r, &se),
        ..Default::default()
    };
    if let Some(d) = rt.d_sky() {
        let ours: Vec<[f64; 3]> = (0..n)
            .map(|j| std::array::from_fn(|c| f64::from(d[c][j])))
            .collect();
        let m: Vec<[f64; 3]> = sky_reference.iter().map(|e| e.mean).collect();
        let e: Vec<[f64; 3]> = sky_reference.iter().map(|e| e.std_error).collect();
        report.sky = Some(compare(&areas, &ours, &m, &e));
    }
    // The real hemisphere's front-face fraction.
    let fronts: Vec<f64> = groups
        .par_iter()
        .enumerate()
        .map(|(j, g)| {
            g.iter()
                .enumerate()
                .map(|(k, (x, nn))| pt.front_fraction(*x, *nn, 256, (j * 64 + k) as u64))
                .sum::<f64>()
                / g.len() as f64
        })
        .collect();
    let atot: f64 = areas.iter().sum();
    report.front_fraction = fronts.iter().zip(&areas).map(|(f, a)| f * a).sum::<f64>() / atot;
    if let Some(sel) = first {
        // The first reflection through F.
        let gpu = Gpu::new(sel).context("opening the OpenCL device")?;
        let backend = Backend::OpenCl(&gpu);
        let vox = voxelize_at(&rt.scene, rt.baked.options.voxel_size, &backend)?;
        let ffo = FormFactorOptions {
            method: crate::bake::form_factor::FormFactorMethod::parse(&rt.baked.options.ff_method)
                .context("the bake's form-factor method")?,
            // 0 in files from before the rays method (contour bakes).
            rays_per_patch: match rt.baked.options.ff_rays_per_patch {
                0 => FormFactorOptions::default().rays_per_patch,
                r => r,
            },
            samples: rt.baked.options.ff_samples,
            rays: rt.baked.options.ff_rays,
            quadrature_tol: rt.baked.options.ff_quadrature_tol,
            ..FormFactorOptions::default()
        };
        let ff = of_voxelization(&rt.scene, &vox, &ffo, &backend, &mut |_, _| {})?;
        if ff.n == n {
            let order = &rt.baked.order;
            let b0 = rt.b0();
            // The run time's first reflection: F (B0 + δ) plus the
            // near-field correction c of the same lights (both zero
            // without one).
            let near = if rt.near.is_empty() {
                let zero = || [vec![0.0; n], vec![0.0; n], vec![0.0; n]];
                NearTerms {
                    c: zero(),
                    delta: zero(),
                }
            } else {
                let m = rt.near.m;
                let (mut d_points, _) = direct::irradiance(&rt.baked, &rt.direct, lights, m);
                // The sky's light at the points, as the frame corrects it
                // (the correction is linear in it).
                if let Some(sky) = rt.d_sky().and_then(|d| rt.near.sky_points(d)) {
                    for (p, s) in d_points.iter_mut().zip(&sky) {
                        for (a, b) in p.iter_mut().zip(s) {
                            *a += b;
                        }
                    }
                }
                rt.near_correction(&d_points)
                    .expect("the bake has a correction")
            };
            let f1: Vec<[f64; 3]> = (0..n)
                .into_par_iter()
                .map(|i| {
                    let row = &ff.f[order[i] as usize * n..(order[i] as usize + 1) * n];
                    std::array::from_fn(|c| {
                        (0..n)
                            .map(|j| {
                                row[order[j] as usize] as f64
                                    * (b0[c][j] as f64 + near.delta[c][j] as f64)
                            })
                            .sum::<f64>()
                            + near.c[c][i] as f64
                    })
                })
                .collect();
            let rows: f64 = (0..n)
                .map(|i| {
                    let s: f64 = ff.f[order[i] as usize * n..(order[i] as usize + 1) * n]
                        .iter()
                        .map(|&v| v as f64)
                        .sum();
                    s * areas[i]
                })
                .sum::<f64>()
                / atot;
            report.row_sum = Some(rows);
            let r1 = pt.mean_over(&groups, lights, paths, Some(1), 0x5eed);
            let r1m: Vec<[f64; 3]> = r1.iter().map(|e| e.mean).collect();
            let r1s: Vec<[f64; 3]> = r1.iter().map(|e| e.std_error).collect();
            report.first_reflection = Some(compare(&areas, &f1, &r1m, &r1s));
            let later_h: Vec<[f64; 3]> = (0..n)
                .map(|j| std::array::from_fn(|c| h[j][c] - f1[j][c]))
                .collect();
            let later_r: Vec<[f64; 3]> = (0..n)
                .map(|j| std::array::from_fn(|c| r[j][c] - r1m[j][c]))
                .collect();
            report.later_bounces = Some(compare(&areas, &later_h, &later_r, &se));
        } else {
            // A bake from an older version: today's voxelizer makes other
            // patches, so its F cannot be matched to the file's rows.
            eprintln!(
                "first reflection not measured: the voxelizer now makes {} patches at this voxel size where the bake has {n} (a bake from an older version)",
                ff.n
            );
        }
    }
    report.seconds_reference = start.elapsed().as_secs_f64();
    let mut s = String::new();
    let pct = |x: f64| format!("{:+.1} %", 100.0 * x);
    writeln!(
        s,
        "{}: {n} patches; reference: {paths} paths from each of {points} points per patch ({:.0} s)",
        path.display(),
        report.seconds_reference
    )?;
    let line = |s: &mut String, name: &str, c: &Comparison| {
        let _ = writeln!(
            s,
            "  {name}: bias {}, relative RMS {:.1} % (reference noise {:.2} %)",
            pct(c.bias),
            100.0 * c.rel_rms,
            100.0 * c.noise
        );
    };
    line(&mut s, "H = T̃ B0", &report.total);
    if let Some(c) = &report.sky {
        line(&mut s, "sky's direct irradiance D_sky (sky cells)", c);
    }
    if let Some(c) = &report.first_reflection {
        line(&mut s, "first reflection F B0 + near field", c);
    }
    if let Some(c) = &report.later_bounces {
        line(&mut s, "later bounces", c);
    }
    if let Some(r) = report.row_sum {
        writeln!(
            s,
            "  F row sums (area-weighted) {r:.3}; real hemisphere meeting front faces {:.3}",
            report.front_fraction
        )?;
    } else {
        writeln!(
            s,
            "  real hemisphere meeting front faces {:.3}",
            report.front_fraction
        )?;
    }
    Ok((report, s))
}

/// Writes one CSV row per patch: index, centre, normal, area, then the
/// bake's `H`, the reference's `H_ref` and its standard error, `B0` and
/// `D`, each as three channels — for finding where the error sits (by
/// size, orientation, place) with any plotting tool.
fn write_per_patch(
    out: &Path,
    rt: &Runtime,
    h: &[[f64; 3]],
    r: &[[f64; 3]],
    se: &[[f64; 3]],
) -> anyhow::Result<()> {
    let mut csv = String::from(
        "patch,x,y,z,nx,ny,nz,area,h_r,h_g,h_b,ref_r,ref_g,ref_b,se_r,se_g,se_b,b0_r,b0_g,b0_b,d_r,d_g,d_b\n",
    );
    for (j, p) in rt.baked.patches.iter().enumerate() {
        let [x, y, z] = p.centre;
        let [nx, ny, nz] = p.normal;
        let _ = write!(csv, "{j},{x},{y},{z},{nx},{ny},{nz},{}", p.area);
        for v in [h[j], r[j], se[j]] {
            let _ = write!(csv, ",{},{},{}", v[0], v[1], v[2]);
        }
        for v in [rt.b0(), rt.d()] {
            let _ = write!(csv, ",{},{},{}", v[0][j], v[1][j], v[2][j]);
        }
        csv.push('\n');
    }
    std::fs::write(out, csv).with_context(|| format!("writing {}", out.display()))
}
