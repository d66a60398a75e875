//! The commands' work, each given its checked job ([`crate::cli::Job`]):
//! the checks that need files (outputs that would overwrite an input,
//! places that cannot take an output), the library call, and what is
//! printed. `render` and `view` are in [`crate::frames`].

use crate::cli::{AccuracyJob, CompressionJob, ExportJob, FrameJob, GenerateJob};
use crate::{frames, outputs};
use anyhow::Context as _;
use radiosity::bake::form_factor::FormFactorOptions;
use radiosity::bake::{self, BakeConfig};
use radiosity::bakefile::baked::describe;
use radiosity::bakefile::container::write_atomic;
use radiosity::bench::transfer::StressCase;
use radiosity::core::compute::{self, Backend, DeviceSelection, Gpu};
use radiosity::{bakefile, bench, core::scene, generate};
use std::path::{Path, PathBuf};

/// `radiosity devices`.
pub(crate) fn devices(json: bool) -> anyhow::Result<()> {
    let devices = compute::devices().context("listing OpenCL devices")?;
    if json {
        println!("{}", serde_json::to_string_pretty(&devices)?);
        return Ok(());
    }
    for d in &devices {
        println!(
            "[{}] {} — {} ({}), {}, {} compute units, {} MiB global, {} MiB max alloc, {} KiB \
             local, fp64 {}",
            d.index,
            d.platform,
            d.name,
            d.kind,
            d.version.trim(),
            d.compute_units,
            d.global_mem_bytes >> 20,
            d.max_mem_alloc_bytes >> 20,
            d.local_mem_bytes >> 10,
            if d.fp64 { "yes" } else { "no" }
        );
    }
    Ok(())
}

/// `radiosity info`: a bake file (by its magic, or a `.rad` name, so that a
/// damaged bake file is reported as one) or a scene.
pub(crate) fn info(path: &Path, json: bool) -> anyhow::Result<()> {
    let is_rad = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("rad"));
    if is_rad || bakefile::is_bake_file(path) {
        let summary = describe(path)?;
        if json {
            println!("{}", serde_json::to_string_pretty(&summary)?);
        } else {
            print!("{summary}");
        }
        return Ok(());
    }
    let s = scene::load(path).with_context(|| format!("loading {}", path.display()))?;
    let summary = s.summary();
    // Where the scene sees faces from behind (the bake gives them a back
    // side there: `bake::winding`).
    let w = bake::winding::check(&s);
    if json {
        let mut v = serde_json::to_value(&summary)?;
        if let Some(map) = v.as_object_mut() {
            map.insert(
                "winding".into(),
                serde_json::json!({
                    "faces_seen_from_behind": w.twinned.len(),
                    "area": w.twinned_area,
                    "materials": w.materials,
                }),
            );
        }
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        print!("{summary}");
        println!("{w} when baked (--as-wound keeps every face as wound)");
    }
    Ok(())
}

/// `radiosity bake`.
pub(crate) fn bake(config: BakeConfig, json: bool) -> anyhow::Result<()> {
    // Before any work: no output over the scene's files, and places that
    // take the outputs.
    let mut inputs = outputs::Inputs::new();
    inputs.scene(&config.scene);
    if let Some(out) = &config.output {
        inputs.check(out, "-o")?;
        outputs::writable(out, "-o")?;
    }
    if let Some(dir) = &config.export {
        let files: Vec<PathBuf> = bake::export::FILES.iter().map(|f| dir.join(f)).collect();
        inputs.check_all(&files, "--export")?;
        outputs::writable_dir(dir, "--export")?;
    }
    let out = bake::run(&config, &mut |line| eprintln!("[bake] {line}")).map_err(|e| {
        // The library names the remedy "two-sided"; here it is a flag.
        let facing = matches!(e, bake::error::BakeError::Facing { .. });
        let e = anyhow::Error::from(e).context(format!("baking {}", config.scene.display()));
        if facing {
            e.context("the faces see nothing (to bake patches on both sides, pass --two-sided)")
        } else {
            e
        }
    })?;
    if json {
        println!("{}", serde_json::to_string_pretty(&out.report)?);
    } else {
        print!("{}", out.report.scene);
        print!("{}", out.report);
    }
    Ok(())
}

/// `radiosity export-mitsuba`.
pub(crate) fn export_mitsuba(job: ExportJob) -> anyhow::Result<()> {
    let ExportJob {
        scene: scene_path,
        output,
        camera_lights,
        options,
    } = job;
    let (scene_path, output) = (scene_path.as_path(), output.as_path());
    let scene = radiosity::core::scene::load(scene_path)
        .with_context(|| format!("loading {}", scene_path.display()))?;
    // Nothing the export writes may be one of the files it reads.
    let mut inputs = outputs::Inputs::new();
    inputs.scene(scene_path);
    if let Some(c) = &camera_lights {
        inputs.file(c, "the camera and lights");
    }
    inputs.check_all(&radiosity::mitsuba::export::files(&scene, output), "-o")?;
    outputs::writable_dir(output, "-o")?;
    let config = frames::camera_lights(camera_lights, scene_path, Some(&scene))?;
    let s = radiosity::mitsuba::export(&scene, &config, options, output)
        .with_context(|| format!("exporting {} to Mitsuba 3", scene_path.display()))?;
    println!(
        "wrote {}: {} meshes, {} textures, {} emitters, {} lights",
        output.display(),
        s.meshes,
        s.textures,
        s.emitters,
        s.lights
    );
    Ok(())
}

/// `radiosity generate`.
pub(crate) fn generate(job: GenerateJob) -> anyhow::Result<()> {
    let (name, dir) = match job {
        GenerateJob::List => {
            for n in generate::BUNDLED {
                println!("{n}");
            }
            for n in generate::STRESS {
                println!("{n} (generated on demand, not committed)");
            }
            return Ok(());
        }
        GenerateJob::Write { name, dir } => (name, dir),
    };
    let written = generate::write_bundled(&name, &dir)
        .with_context(|| format!("generating scene {name} into {}", dir.display()))?;
    for p in written {
        println!("wrote {}", p.display());
    }
    Ok(())
}

/// `radiosity bench accuracy`.
pub(crate) fn bench_accuracy(job: AccuracyJob) -> anyhow::Result<()> {
    use radiosity::bakefile::baked::{resolve_scene_path, Baked};
    if let Some(csv) = &job.per_patch {
        let mut inputs = outputs::Inputs::new();
        inputs.file(&job.bake, "the bake");
        if let Some(c) = &job.camera_lights {
            inputs.file(c, "the camera and lights");
        }
        inputs.check(csv, "--per-patch")?;
        outputs::writable(csv, "--per-patch")?;
        outputs::make_parent(csv)?;
    }
    let info = Baked::load(&job.bake)?.info;
    let config = frames::camera_lights(
        job.camera_lights,
        &resolve_scene_path(&job.bake, &info.scene),
        None,
    )?;
    let (report, text) = bench::accuracy::run(
        &job.bake,
        &config,
        job.paths,
        job.points,
        job.first_reflection,
        job.per_patch.as_deref(),
        job.near_field,
    )?;
    if job.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print!("{text}");
    }
    Ok(())
}

/// `radiosity bench stress`.
pub(crate) fn bench_stress(patches: usize, selection: DeviceSelection) -> anyhow::Result<()> {
    let table = bench::stress::run(patches, selection, &mut |l| eprintln!("[stress] {l}"))?;
    print!("{table}");
    Ok(())
}

/// `radiosity bench sweep`.
pub(crate) fn bench_sweep(options: bench::sweep::SweepOptions) -> anyhow::Result<()> {
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

/// `radiosity bench skips`.
pub(crate) fn bench_skips(options: bench::skips::SkipsOptions) -> anyhow::Result<()> {
    bench::skips::run(&options, &mut |l| eprintln!("[skips] {l}"))?;
    println!("{}", options.out.join("skips.md").display());
    Ok(())
}

/// The camera and lights of the bake at `bake`: `given`, else its scene's
/// `NAME.json` (made when missing).
fn bake_camera_lights(
    bake: &Path,
    given: Option<PathBuf>,
) -> anyhow::Result<radiosity::core::scene_config::SceneConfig> {
    use radiosity::bakefile::baked::{resolve_scene_path, Baked};
    let info = Baked::load(bake)?.info;
    frames::camera_lights(given, &resolve_scene_path(bake, &info.scene), None)
}

/// `radiosity bench frame`.
pub(crate) fn bench_frame(job: FrameJob) -> anyhow::Result<()> {
    let bake = &job.bake;
    let config = bake_camera_lights(bake, job.camera_lights)?;
    let report = bench::frame::run(bake, &config, &job.options)
        .with_context(|| format!("benchmarking frames of {}", bake.display()))?;
    print!("{report}");
    Ok(())
}

/// `radiosity bench probes`.
pub(crate) fn bench_probes(job: crate::cli::ProbesJob) -> anyhow::Result<()> {
    let bake = &job.bake;
    let config = bake_camera_lights(bake, job.camera_lights)?;
    let (report, _) = bench::probes::run(bake, &config, &job.options)
        .with_context(|| format!("comparing the probes of {} with Mitsuba 3", bake.display()))?;
    print!("{report}");
    Ok(())
}

/// `radiosity bench voxelize`.
pub(crate) fn bench_voxelize(
    scene: &Path,
    voxel_sizes: &[f64],
    repeat: usize,
    selection: DeviceSelection,
) -> anyhow::Result<()> {
    let table = bench::voxelize::run(scene, voxel_sizes, repeat, selection)
        .with_context(|| format!("benchmarking voxelization of {}", scene.display()))?;
    print!("{table}");
    Ok(())
}

/// `radiosity bench form-factors`.
pub(crate) fn bench_form_factors(
    scene: &Path,
    patches: &[usize],
    options: &FormFactorOptions,
    cpu_reference: bool,
    selection: DeviceSelection,
) -> anyhow::Result<()> {
    let table = bench::form_factor::run(scene, patches, options, selection, cpu_reference)
        .with_context(|| format!("benchmarking form factors of {}", scene.display()))?;
    print!("{table}");
    Ok(())
}

/// `radiosity bench solve`.
pub(crate) fn bench_solve(
    scene: &Path,
    patches: &[usize],
    selection: DeviceSelection,
) -> anyhow::Result<()> {
    let gpu = Gpu::new(selection).context("opening the OpenCL device")?;
    let backend = Backend::OpenCl(&gpu);
    println!(
        "## T_inf of {}: LU solve and doubling against f64 (channel R)\n",
        scene.display()
    );
    let table =
        bench::transfer::bench_solve(scene, patches, &backend, &mut |l| eprintln!("[bench] {l}"))?;
    print!("{table}");
    Ok(())
}

/// `radiosity bench transfer`.
pub(crate) fn bench_transfer(
    gemm_sizes: &[usize],
    stress_sizes: &[usize],
    rooms: usize,
    albedos: &[f64],
    selection: DeviceSelection,
) -> anyhow::Result<()> {
    let gpu = Gpu::new(selection).context("opening the OpenCL device")?;
    let backend = Backend::OpenCl(&gpu);
    println!("## GEMM: OpenCL against faer (f32), same run\n");
    print!("{}", bench::transfer::bench_gemm(gemm_sizes, 3, &backend)?);
    let cases: Vec<StressCase> = stress_sizes
        .iter()
        .map(|&n| StressCase { n, rooms })
        .collect();
    println!("\n## T_inf stress: error against the f64 reference\n");
    print!(
        "{}",
        bench::transfer::bench_stress(&cases, albedos, &backend)?
    );
    Ok(())
}

/// `radiosity bench compression`.
pub(crate) fn bench_compression(job: CompressionJob) -> anyhow::Result<()> {
    let CompressionJob {
        scenes,
        options,
        output,
    } = job;
    if let Some(path) = &output {
        let mut inputs = outputs::Inputs::new();
        for (s, _) in &scenes {
            inputs.scene(s);
        }
        inputs.check(path, "-o")?;
        outputs::writable(path, "-o")?;
    }
    let mut args: Vec<String> = std::env::args().collect();
    args[0] = "radiosity".into();
    let report = bench::compression::compression_report(
        &scenes,
        &options,
        &bench::shell_command_line(&args),
        &mut |line| eprintln!("[compression] {line}"),
    )
    .context("compression report")?;
    match output {
        Some(path) => {
            outputs::make_parent(&path)?;
            write_atomic(&path, report.as_bytes(), None)
                .with_context(|| format!("writing {}", path.display()))?;
            eprintln!("wrote {}", path.display());
        }
        None => print!("{report}"),
    }
    Ok(())
}
