//! The `radiosity` command line. Flags are parsed by clap into raw structs,
//! turned into validated config structs from the library, and every error
//! is printed with its whole context chain and a non-zero exit code.

use anyhow::{bail, Context as _};
use clap::{Args, Parser, Subcommand};
use radiosity::bake::{self, BakeConfig, ComputeChoice};
use radiosity::compute::Gpu;
use radiosity::compute::{self, DeviceSelection};
use radiosity::form_factor::FormFactorOptions;
use radiosity::transfer::{Bounces, StressCase, TransferOptions};
use radiosity::voxelize::{Backend, Resolution};
use radiosity::{bench, form_factor, gemm, generate, scene, transfer};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "radiosity",
    version,
    about = "Real-time radiosity: bake a compressed multi-bounce transfer matrix for a static diffuse scene",
    long_about = None
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// List OpenCL platforms and devices (the index is what --device takes).
    Devices {
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Describe a scene (.obj): triangles, materials, bounds, areas, repairs.
    Info {
        /// The scene file.
        path: PathBuf,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Bake a scene: load, voxelize, form factors, transfer matrix, report.
    Bake(BakeArgs),
    /// Write a bundled scene (OBJ + MTL + camera/lights JSON) into a directory.
    Generate {
        /// Scene name (see --list).
        #[arg(required_unless_present = "list")]
        name: Option<String>,
        /// Output directory (default: scenes/NAME).
        #[arg(short, long)]
        output: Option<PathBuf>,
        /// List the bundled scene names.
        #[arg(long)]
        list: bool,
    },
    /// Benchmarks (time with error against a named reference).
    Bench {
        #[command(subcommand)]
        which: BenchCommand,
    },
}

#[derive(Subcommand)]
enum BenchCommand {
    /// Voxelization: OpenCL against the CPU reference at several voxel sizes.
    Voxelize {
        /// The scene file.
        scene: PathBuf,
        /// Comma-separated voxel sizes in scene units.
        #[arg(long, value_delimiter = ',', required = true)]
        voxel_sizes: Vec<f64>,
        /// Repetitions per size (the fastest is reported).
        #[arg(long, default_value_t = 3)]
        repeat: usize,
        #[command(flatten)]
        device: DeviceArgs,
    },
    /// Form factors: OpenCL and the CPU reference at several patch counts.
    FormFactors {
        /// The scene file.
        scene: PathBuf,
        /// Comma-separated target patch counts.
        #[arg(long, value_delimiter = ',', required = true)]
        patches: Vec<usize>,
        /// Skip the (slow) CPU reference.
        #[arg(long)]
        no_cpu_reference: bool,
        #[command(flatten)]
        device: DeviceArgs,
    },
    /// Transfer stage: GEMM throughput against faer, and the stress table
    /// (error against the f64 reference over albedos and sizes).
    Transfer {
        /// Comma-separated GEMM sizes.
        #[arg(long, value_delimiter = ',', default_value = "1024,2048")]
        gemm_sizes: Vec<usize>,
        /// Comma-separated stress sizes n (closed synthetic rooms).
        #[arg(long, value_delimiter = ',', default_value = "1024")]
        stress_sizes: Vec<usize>,
        /// Rooms per stress case (block-diagonal F; 1 = dense).
        #[arg(long, default_value_t = 1)]
        rooms: usize,
        /// Comma-separated albedos for the stress table.
        #[arg(long, value_delimiter = ',', default_value = "0.5,0.9,0.99,0.999")]
        albedos: Vec<f64>,
        #[command(flatten)]
        device: DeviceArgs,
    },
}

#[derive(Args, Clone)]
struct DeviceArgs {
    /// OpenCL device index (see `radiosity devices`); overrides RADIOSITY_CL_DEVICE.
    #[arg(long, value_name = "INDEX")]
    device: Option<usize>,
}

#[derive(Args)]
struct BakeArgs {
    /// The scene (.obj with its .mtl).
    scene: PathBuf,
    /// Output bake file (written once the later stages exist; accepted now
    /// so scripts need not change).
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Voxel edge length in scene units.
    #[arg(long, conflicts_with = "patches")]
    voxel_size: Option<f64>,
    /// Target patch count; the voxel size is searched for. Default 2000.
    #[arg(long)]
    patches: Option<usize>,
    /// Light bounces folded into the transfer matrix: a number k >= 1, or
    /// `inf` for the converged limit (default: inf).
    #[arg(long, value_parser = parse_bounces)]
    bounces: Option<Bounces>,
    /// Form-factor emitter samples per side (1..=16, default 4).
    #[arg(long)]
    ff_samples: Option<u32>,
    /// Form-factor visibility rays per patch pair (1..=64, default 4).
    #[arg(long)]
    ff_rays: Option<u32>,
    /// Write inspection files (patches.csv, patches.png, F.npy, T.npy,
    /// albedo.npy) into this directory.
    #[arg(long, value_name = "DIR")]
    export: Option<PathBuf>,
    /// Run every stage on the CPU reference instead of OpenCL.
    #[arg(long, conflicts_with = "device")]
    cpu_reference: bool,
    #[command(flatten)]
    device: DeviceArgs,
    /// Print the report as JSON on stdout.
    #[arg(long)]
    json: bool,
}

impl BakeArgs {
    /// Raw flags → validated config.
    fn into_config(self) -> anyhow::Result<(BakeConfig, bool)> {
        let resolution = match (self.voxel_size, self.patches) {
            (Some(s), _) => Resolution::VoxelSize(s),
            (None, Some(n)) => Resolution::Patches(n),
            (None, None) => Resolution::Patches(2000),
        };
        let compute = if self.cpu_reference {
            ComputeChoice::CpuReference
        } else {
            ComputeChoice::OpenCl(DeviceSelection::from_flag_or_env(self.device.device)?)
        };
        if let Some(out) = &self.output {
            eprintln!(
                "note: the bake file format comes with a later stage; {} is not written yet",
                out.display()
            );
        }
        let mut form_factor = FormFactorOptions::default();
        if let Some(m) = self.ff_samples {
            form_factor.samples = m;
        }
        if let Some(r) = self.ff_rays {
            form_factor.rays = r;
        }
        let transfer = TransferOptions {
            bounces: self.bounces.unwrap_or_default(),
            ..TransferOptions::default()
        };
        let config = BakeConfig {
            scene: self.scene,
            resolution,
            compute,
            form_factor,
            transfer,
            export: self.export,
        };
        config.validate()?;
        Ok((config, self.json))
    }
}

/// `--bounces`: a positive integer or `inf`.
fn parse_bounces(s: &str) -> Result<Bounces, String> {
    match s.trim() {
        "inf" | "infinite" | "∞" => Ok(Bounces::Infinite),
        v => match v.parse::<u32>() {
            Ok(k) if k >= 1 => Ok(Bounces::K(k)),
            _ => Err(format!(
                "expected a number of bounces >= 1 or `inf`, got {s:?}"
            )),
        },
    }
}

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
        Command::Devices { json } => {
            let devices = compute::devices().context("listing OpenCL devices")?;
            if json {
                println!("{}", serde_json::to_string_pretty(&devices)?);
            } else {
                for d in &devices {
                    println!(
                        "[{}] {} — {} ({}), {}, {} compute units, {} MiB global, {} MiB max alloc, {} KiB local, fp64 {}",
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
                println!("GL renderer: not part of this build yet (the renderer comes with a later stage)");
            }
        }
        Command::Info { path, json } => {
            let s = scene::load(&path).with_context(|| format!("loading {}", path.display()))?;
            let summary = s.summary();
            if json {
                println!("{}", serde_json::to_string_pretty(&summary)?);
            } else {
                print!("{summary}");
            }
        }
        Command::Bake(args) => {
            let (config, json) = args.into_config()?;
            let out = bake::run(&config, &mut |line| eprintln!("[bake] {line}"))
                .with_context(|| format!("baking {}", config.scene.display()))?;
            if json {
                println!("{}", serde_json::to_string_pretty(&out.report)?);
            } else {
                print!("{}", out.report.scene);
                print!("{}", out.report);
            }
        }
        Command::Generate { name, output, list } => {
            if list {
                for n in generate::BUNDLED {
                    println!("{n}");
                }
                return Ok(());
            }
            let name = name.expect("clap requires NAME without --list");
            let dir = output.unwrap_or_else(|| PathBuf::from("scenes").join(&name));
            let written = generate::write_bundled(&name, &dir)
                .with_context(|| format!("generating scene {name} into {}", dir.display()))?;
            for p in written {
                println!("wrote {}", p.display());
            }
        }
        Command::Bench { which } => match which {
            BenchCommand::Voxelize {
                scene,
                voxel_sizes,
                repeat,
                device,
            } => {
                if repeat == 0 {
                    bail!("--repeat must be at least 1");
                }
                let selection = DeviceSelection::from_flag_or_env(device.device)?;
                let table = bench::voxelize(&scene, &voxel_sizes, repeat, selection)
                    .with_context(|| format!("benchmarking voxelization of {}", scene.display()))?;
                print!("{table}");
            }
            BenchCommand::FormFactors {
                scene,
                patches,
                no_cpu_reference,
                device,
            } => {
                let selection = DeviceSelection::from_flag_or_env(device.device)?;
                let table = form_factor::bench(
                    &scene,
                    &patches,
                    &FormFactorOptions::default(),
                    selection,
                    !no_cpu_reference,
                )
                .with_context(|| format!("benchmarking form factors of {}", scene.display()))?;
                print!("{table}");
            }
            BenchCommand::Transfer {
                gemm_sizes,
                stress_sizes,
                rooms,
                albedos,
                device,
            } => {
                let gpu = Gpu::new(DeviceSelection::from_flag_or_env(device.device)?)
                    .context("opening the OpenCL device")?;
                let backend = Backend::OpenCl(&gpu);
                println!("## GEMM: OpenCL against faer (f32), same run\n");
                print!("{}", gemm::bench_gemm(&gemm_sizes, 3, &backend)?);
                let cases: Vec<StressCase> = stress_sizes
                    .iter()
                    .map(|&n| StressCase { n, rooms })
                    .collect();
                println!("\n## T_inf stress: error against the f64 reference\n");
                print!("{}", transfer::bench_stress(&cases, &albedos, &backend)?);
            }
        },
    }
    Ok(())
}
