//! The `radiosity` command line. Flags are parsed by clap into raw structs,
//! turned into validated config structs from the library, and every error
//! is printed with its whole context chain and a non-zero exit code.

use anyhow::{bail, Context as _};
use clap::Parser;
use radiosity::bake;
use radiosity::bake::form_factor::FormFactorOptions;
use radiosity::bake::reorder::ReorderMethod;
use radiosity::bakefile::baked::describe;
use radiosity::bakefile::codec::CodecKind;
use radiosity::bakefile::container::write_atomic;
use radiosity::bench::transfer::StressCase;
use radiosity::core::compute::Backend;
use radiosity::core::compute::Gpu;
use radiosity::core::compute::{self, DeviceSelection};
use radiosity::{bakefile, bench, core::scene, generate};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

mod frames;
mod outputs;
mod reports;

mod cli;
use cli::{BakeArgs, BenchCommand, Cli, Command, DeviceArgs};

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            for cause in e.chain().skip(1) {
                eprintln!("  caused by: {cause}");
            }
            ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Devices { json } => devices(json),
        Command::Info { path, json } => info(&path, json),
        Command::Bake(args) => bake(args),
        Command::Render(args) => frames::render(args),
        Command::View(args) => frames::view(args),
        Command::Generate { name, output, list } => generate(name, output, list),
        Command::ExportMitsuba {
            scene,
            output,
            camera_lights,
            width,
            height,
            two_sided,
        } => export_mitsuba(&scene, &output, camera_lights, width, height, two_sided),
        Command::Bench { which } => match which {
            BenchCommand::Accuracy {
                bake,
                camera_lights: cl,
                paths,
                points,
                first_reflection,
                json,
                per_patch,
                no_near_field,
                device,
            } => {
                use radiosity::bakefile::baked::{resolve_scene_path, Baked};
                if paths == 0 {
                    bail!("--paths must be at least 1");
                }
                if let Some(csv) = &per_patch {
                    let mut inputs = outputs::Inputs::new();
                    inputs.file(&bake, "the bake");
                    if let Some(c) = &cl {
                        inputs.file(c, "the camera and lights");
                    }
                    inputs.check(csv, "--per-patch")?;
                    outputs::writable(csv, "--per-patch")?;
                    outputs::make_parent(csv)?;
                }
                let info = Baked::load(&bake)?.info;
                let config =
                    frames::camera_lights(cl, &resolve_scene_path(&bake, &info.scene), None)?;
                let sel = if first_reflection {
                    Some(DeviceSelection::from_flag_or_env(device.device)?)
                } else {
                    None
                };
                let (report, text) = bench::accuracy::run(
                    &bake,
                    &config,
                    paths,
                    points,
                    sel,
                    per_patch.as_deref(),
                    !no_near_field,
                )?;
                if json {
                    println!("{}", serde_json::to_string_pretty(&report)?);
                } else {
                    print!("{text}");
                }
                Ok(())
            }
            BenchCommand::Stress { patches, device } => {
                if patches == 0 {
                    bail!("--patches must be at least 1");
                }
                let selection = DeviceSelection::from_flag_or_env(device.device)?;
                let table =
                    bench::stress::run(patches, selection, &mut |l| eprintln!("[stress] {l}"))?;
                print!("{table}");
                Ok(())
            }
            BenchCommand::Skips {
                scenes,
                patches,
                repeat,
                output,
                device,
            } => reports::bench_skips(scenes, patches, repeat, output, device),
            BenchCommand::Sweep {
                quick,
                scenes,
                patches,
                bounces,
                codecs,
                reorders,
                repeat,
                no_gl,
                baseline_only,
                output,
                max_error,
                max_image_error,
                no_images,
                references,
                reference_size,
                reference_spp,
                device,
            } => reports::bench_sweep(reports::SweepArgs {
                quick,
                scenes,
                patches,
                bounces,
                codecs,
                reorders,
                repeat,
                gl: !no_gl,
                baseline_only,
                output,
                max_error,
                max_image_error,
                no_images,
                references,
                reference_size,
                reference_spp,
                device,
            }),
            BenchCommand::Frame {
                bake,
                camera_lights,
                repeat,
                width,
                height,
                no_classic,
                device,
            } => bench_frame(
                &bake,
                camera_lights,
                repeat,
                width,
                height,
                !no_classic,
                device,
            ),
            BenchCommand::Voxelize {
                scene,
                voxel_sizes,
                repeat,
                device,
            } => bench_voxelize(&scene, &voxel_sizes, repeat, device),
            BenchCommand::FormFactors {
                scene,
                patches,
                no_cpu_reference,
                device,
            } => bench_form_factors(&scene, &patches, no_cpu_reference, device),
            BenchCommand::Solve {
                scene,
                patches,
                device,
            } => {
                let gpu = Gpu::new(DeviceSelection::from_flag_or_env(device.device)?)
                    .context("opening the OpenCL device")?;
                let backend = Backend::OpenCl(&gpu);
                println!(
                    "## T_inf of {}: LU solve and doubling against f64 (channel R)\n",
                    scene.display()
                );
                let table = bench::transfer::bench_solve(&scene, &patches, &backend, &mut |l| {
                    eprintln!("[bench] {l}")
                })?;
                print!("{table}");
                Ok(())
            }
            BenchCommand::Transfer {
                gemm_sizes,
                stress_sizes,
                rooms,
                albedos,
                device,
            } => bench_transfer(&gemm_sizes, &stress_sizes, rooms, &albedos, device),
            BenchCommand::Compression {
                scenes,
                patches,
                reorder,
                codecs,
                lights,
                seed,
                output,
                device,
            } => bench_compression(
                scenes, patches, reorder, codecs, lights, seed, output, device,
            ),
        },
    }
}

/// `radiosity devices`.
fn devices(json: bool) -> anyhow::Result<()> {
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
fn info(path: &Path, json: bool) -> anyhow::Result<()> {
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
fn bake(args: BakeArgs) -> anyhow::Result<()> {
    let (config, json) = args.into_config()?;
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
        if let Some(out) = &config.output {
            if files.iter().any(|f| f == out) {
                bail!(
                    "-o {} is one of the files --export writes into {}",
                    out.display(),
                    dir.display()
                );
            }
        }
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
fn export_mitsuba(
    scene_path: &Path,
    output: &Path,
    camera_lights: Option<PathBuf>,
    width: usize,
    height: usize,
    two_sided: bool,
) -> anyhow::Result<()> {
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
    let options = radiosity::mitsuba::ExportOptions {
        width,
        height,
        two_sided,
    };
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
fn generate(name: Option<String>, output: Option<PathBuf>, list: bool) -> anyhow::Result<()> {
    if list {
        for n in generate::BUNDLED {
            println!("{n}");
        }
        for n in generate::STRESS {
            println!("{n} (generated on demand, not committed)");
        }
        return Ok(());
    }
    let name = name.context("a scene name is required (see --list)")?;
    let dir = output.unwrap_or_else(|| PathBuf::from("scenes").join(&name));
    let written = generate::write_bundled(&name, &dir)
        .with_context(|| format!("generating scene {name} into {}", dir.display()))?;
    for p in written {
        println!("wrote {}", p.display());
    }
    Ok(())
}

/// `radiosity bench frame`.
fn bench_frame(
    bake: &Path,
    camera_lights_file: Option<PathBuf>,
    repeat: usize,
    width: usize,
    height: usize,
    classic: bool,
    device: DeviceArgs,
) -> anyhow::Result<()> {
    use radiosity::bakefile::baked::{resolve_scene_path, Baked};
    if repeat == 0 {
        bail!("--repeat must be at least 1");
    }
    frames::check_image_size(width, height)?;
    let info = Baked::load(bake)?.info;
    let config = frames::camera_lights(
        camera_lights_file,
        &resolve_scene_path(bake, &info.scene),
        None,
    )?;
    let options = bench::frame::FrameBenchOptions {
        repeat,
        width,
        height,
        selection: DeviceSelection::from_flag_or_env(device.device)?,
        classic,
    };
    let report = bench::frame::run(bake, &config, &options)
        .with_context(|| format!("benchmarking frames of {}", bake.display()))?;
    print!("{report}");
    Ok(())
}

/// `radiosity bench voxelize`.
fn bench_voxelize(
    scene: &Path,
    voxel_sizes: &[f64],
    repeat: usize,
    device: DeviceArgs,
) -> anyhow::Result<()> {
    if repeat == 0 {
        bail!("--repeat must be at least 1");
    }
    let selection = DeviceSelection::from_flag_or_env(device.device)?;
    let table = bench::voxelize::run(scene, voxel_sizes, repeat, selection)
        .with_context(|| format!("benchmarking voxelization of {}", scene.display()))?;
    print!("{table}");
    Ok(())
}

/// `radiosity bench form-factors`.
fn bench_form_factors(
    scene: &Path,
    patches: &[usize],
    no_cpu_reference: bool,
    device: DeviceArgs,
) -> anyhow::Result<()> {
    let selection = DeviceSelection::from_flag_or_env(device.device)?;
    let table = bench::form_factor::run(
        scene,
        patches,
        &FormFactorOptions::default(),
        selection,
        !no_cpu_reference,
    )
    .with_context(|| format!("benchmarking form factors of {}", scene.display()))?;
    print!("{table}");
    Ok(())
}

/// `radiosity bench transfer`.
fn bench_transfer(
    gemm_sizes: &[usize],
    stress_sizes: &[usize],
    rooms: usize,
    albedos: &[f64],
    device: DeviceArgs,
) -> anyhow::Result<()> {
    let gpu = Gpu::new(DeviceSelection::from_flag_or_env(device.device)?)
        .context("opening the OpenCL device")?;
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
#[allow(clippy::too_many_arguments)]
fn bench_compression(
    scenes: Vec<PathBuf>,
    patches: Vec<usize>,
    reorder: Vec<ReorderMethod>,
    codecs: Vec<CodecKind>,
    lights: usize,
    seed: u64,
    output: Option<PathBuf>,
    device: DeviceArgs,
) -> anyhow::Result<()> {
    let patches = match patches.len() {
        1 => vec![patches[0]; scenes.len()],
        k if k == scenes.len() => patches,
        k => bail!(
            "--patches takes one count or one per scene: got {k} for {} scenes",
            scenes.len()
        ),
    };
    if let Some(&p) = patches.iter().find(|&&p| p == 0) {
        bail!("--patches must be at least 1, got {p}");
    }
    let options = bench::compression::CompressionOptions {
        methods: reorder,
        kinds: if codecs.is_empty() {
            bench::compression::default_compression_kinds()
        } else {
            codecs
        },
        lights,
        seed,
        selection: DeviceSelection::from_flag_or_env(device.device)?,
    };
    if let Some(path) = &output {
        let mut inputs = outputs::Inputs::new();
        for s in &scenes {
            inputs.scene(s);
        }
        inputs.check(path, "-o")?;
        outputs::writable(path, "-o")?;
    }
    let mut args: Vec<String> = std::env::args().collect();
    args[0] = "radiosity".into();
    let scenes: Vec<(PathBuf, usize)> = scenes.into_iter().zip(patches).collect();
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
