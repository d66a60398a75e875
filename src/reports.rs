//! `radiosity bench sweep` and `radiosity bench skips` (a module of the
//! binary): the scene lists (the bundled scenes, Sponza by path when
//! present), the flags checked and turned into the library's options.

use crate::cli::DeviceArgs;
use anyhow::{bail, Context as _};
use radiosity::bench;
use radiosity::core::compute::DeviceSelection;
use std::path::{Path, PathBuf};

/// The flags of `bench sweep`.
pub(crate) struct SweepArgs {
    pub(crate) quick: bool,
    pub(crate) scenes: Vec<String>,
    pub(crate) patches: Vec<usize>,
    pub(crate) bounces: Vec<u32>,
    pub(crate) codecs: Option<String>,
    pub(crate) reorders: Vec<String>,
    pub(crate) repeat: usize,
    pub(crate) gl: bool,
    pub(crate) baseline_only: bool,
    pub(crate) output: PathBuf,
    pub(crate) max_error: f64,
    pub(crate) max_image_error: f64,
    pub(crate) no_images: bool,
    pub(crate) references: Option<PathBuf>,
    pub(crate) reference_size: Option<String>,
    pub(crate) reference_spp: Option<u32>,
    pub(crate) device: DeviceArgs,
}

/// A bundled scene's OBJ: under `scenes/` of the working directory, else
/// of the source tree this binary was built from.
fn bundled_scene_path(name: &str) -> anyhow::Result<PathBuf> {
    let rel = Path::new("scenes").join(name).join(format!("{name}.obj"));
    let candidates = [
        rel.clone(),
        Path::new(env!("CARGO_MANIFEST_DIR")).join(&rel),
    ];
    candidates
        .iter()
        .find(|p| p.exists())
        .cloned()
        .with_context(|| {
            format!(
                "the bundled scene {} is not here: run from the repository root, or give --scenes",
                rel.display()
            )
        })
}

/// `radiosity bench sweep`.
pub(crate) fn bench_sweep(a: SweepArgs) -> anyhow::Result<()> {
    use bench::sweep::{SweepOptions, SweepScene};
    let selection = DeviceSelection::from_flag_or_env(a.device.device)?;
    if a.repeat == 0 {
        bail!("--repeat must be at least 1");
    }
    if a.max_image_error.is_nan() || a.max_image_error <= 0.0 {
        bail!(
            "--max-image-error {}: expected a positive bound",
            a.max_image_error
        );
    }
    if a.max_error.is_nan() || a.max_error <= 0.0 {
        bail!("--max-error {}: expected a positive bound", a.max_error);
    }
    let bundled = |name: &str| -> anyhow::Result<SweepScene> {
        let obj = bundled_scene_path(name)?;
        Ok(SweepScene {
            camera_lights: obj.with_extension("json"),
            obj,
        })
    };
    let mut options = if a.quick {
        SweepOptions::quick(bundled("cornell_box")?, a.output.clone(), selection)
    } else {
        let mut scenes = Vec::new();
        if a.scenes.is_empty() {
            scenes.push(bundled("cornell_box")?);
            scenes.push(bundled("interior")?);
            scenes.extend(sponza_scene());
        } else {
            for s in &a.scenes {
                scenes.push(bench_scene(s)?);
            }
        }
        SweepOptions {
            scenes,
            patches: vec![500, 2000, 4000],
            bounces: vec![1, 2, 3],
            codecs: ["bc1:top=0", "bc4", "bc6h", "f16"]
                .iter()
                .map(|c| radiosity::bakefile::codec::CodecKind::parse(c))
                .collect::<Result<_, _>>()?,
            reorders: vec![
                radiosity::bake::reorder::ReorderMethod::None,
                radiosity::bake::reorder::ReorderMethod::SpaceFillingCurve,
            ],
            repeat: a.repeat,
            gl: a.gl,
            selection,
            out: a.output.clone(),
            max_h_error: a.max_error,
            max_image_error: a.max_image_error,
            references: Some(bench::images::ReferenceOptions {
                dir: a.output.join("reference"),
                width: 320,
                height: 240,
                spp: 1024,
            }),
        }
    };
    if !a.patches.is_empty() {
        if a.patches.contains(&0) {
            bail!("--patches: counts must be at least 1");
        }
        options.patches = a.patches.clone();
    }
    if !a.bounces.is_empty() {
        if a.bounces.contains(&0) {
            bail!("--bounces: counts must be at least 1 (the baseline is ∞)");
        }
        options.bounces = a.bounces.clone();
    }
    if let Some(c) = &a.codecs {
        options.codecs = c
            .split(';')
            .filter(|s| !s.trim().is_empty())
            .map(|s| {
                radiosity::bakefile::codec::CodecKind::parse(s)
                    .with_context(|| format!("--codecs {s:?}"))
            })
            .collect::<anyhow::Result<_>>()?;
    }
    if !a.reorders.is_empty() {
        options.reorders = a
            .reorders
            .iter()
            .map(|r| {
                radiosity::bake::reorder::ReorderMethod::parse(r)
                    .with_context(|| format!("--reorders {r:?}"))
            })
            .collect::<anyhow::Result<_>>()?;
    }
    if a.quick {
        options.repeat = a.repeat.min(2);
        options.gl = a.gl;
        options.max_h_error = a.max_error;
        options.max_image_error = a.max_image_error.min(options.max_image_error);
    }
    if a.baseline_only {
        options.bounces.clear();
        options.codecs.clear();
        options.reorders.clear();
    }
    if a.no_images {
        options.references = None;
    } else if let Some(r) = options.references.as_mut() {
        if let Some(dir) = &a.references {
            r.dir = dir.clone();
        }
        if let Some(size) = &a.reference_size {
            let parsed = size
                .split_once('x')
                .and_then(|(w, h)| Some((w.parse::<usize>().ok()?, h.parse::<usize>().ok()?)))
                .filter(|&(w, h)| (1..=4096).contains(&w) && (1..=4096).contains(&h));
            let Some((w, h)) = parsed else {
                bail!("--reference-size {size:?}: expected WxH, each 1..=4096");
            };
            (r.width, r.height) = (w, h);
        }
        if let Some(spp) = a.reference_spp {
            if spp < 2 || spp % 2 == 1 {
                bail!("--reference-spp {spp}: expected an even count of at least 2");
            }
            r.spp = spp;
        }
    }
    let start = std::time::Instant::now();
    let points = bench::sweep::run(&options, &mut |line| eprintln!("[sweep] {line}"))?;
    eprintln!(
        "[sweep] {} points in {:.1} s",
        points.len(),
        start.elapsed().as_secs_f64()
    );
    println!("{}", options.out.join("sweep.md").display());
    Ok(())
}

/// A scene argument of the benchmarks: SCENE.obj (lights in SCENE.json)
/// or SCENE.obj=LIGHTS.json.
fn bench_scene(s: &str) -> anyhow::Result<bench::sweep::SweepScene> {
    let (obj, json) = match s.split_once('=') {
        Some((o, j)) => (PathBuf::from(o), PathBuf::from(j)),
        None => (PathBuf::from(s), PathBuf::from(s).with_extension("json")),
    };
    if !obj.exists() {
        bail!("--scenes: {} does not exist", obj.display());
    }
    if !json.exists() {
        bail!(
            "--scenes: the camera and lights {} do not exist (give SCENE.obj=LIGHTS.json)",
            json.display()
        );
    }
    Ok(bench::sweep::SweepScene {
        obj,
        camera_lights: json,
    })
}

/// Sponza by path with its camera and lights, when present.
fn sponza_scene() -> Option<bench::sweep::SweepScene> {
    let sponza = PathBuf::from("../shared/scenes/sponza/sponza.obj");
    let lights = bundled_scene_path("cornell_box")
        .ok()?
        .parent()
        .and_then(|p| p.parent())
        .map(|p| p.join("external").join("sponza.json"))?;
    sponza.exists().then_some(bench::sweep::SweepScene {
        obj: sponza,
        camera_lights: lights,
    })
}

/// `radiosity bench skips`.
pub(crate) fn bench_skips(
    scenes: Vec<String>,
    patches: usize,
    repeat: usize,
    output: PathBuf,
    device: DeviceArgs,
) -> anyhow::Result<()> {
    if patches == 0 {
        bail!("--patches must be at least 1");
    }
    if repeat == 0 {
        bail!("--repeat must be at least 1");
    }
    let mut list = Vec::new();
    if scenes.is_empty() {
        for name in ["cornell_box", "interior", "closed_cube"] {
            let obj = bundled_scene_path(name)?;
            list.push(bench::sweep::SweepScene {
                camera_lights: obj.with_extension("json"),
                obj,
            });
        }
        list.extend(sponza_scene());
    } else {
        for s in &scenes {
            list.push(bench_scene(s)?);
        }
    }
    let options = bench::skips::SkipsOptions {
        scenes: list,
        patches,
        repeat,
        selection: DeviceSelection::from_flag_or_env(device.device)?,
        out: output,
    };
    bench::skips::run(&options, &mut |l| eprintln!("[skips] {l}"))?;
    println!("{}", options.out.join("skips.md").display());
    Ok(())
}
