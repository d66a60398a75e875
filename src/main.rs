//! The `radiosity` command line. Flags are parsed by clap into raw structs,
//! turned into validated config structs from the library, and every error
//! is printed with its whole context chain and a non-zero exit code.

use anyhow::{bail, Context as _};
use clap::{Args, Parser, Subcommand};
use radiosity::bake::{self, BakeConfig, ComputeChoice};
use radiosity::compute::{self, DeviceSelection};
use radiosity::voxelize::Resolution;
use radiosity::{bench, generate, scene};
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
    /// Bake a scene. At this stage of the project: load, voxelize, report.
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
    /// Write inspection files (patches.csv) into this directory.
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
        let config = BakeConfig {
            scene: self.scene,
            resolution,
            compute,
            export: self.export,
        };
        config.validate()?;
        Ok((config, self.json))
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
        },
    }
    Ok(())
}
