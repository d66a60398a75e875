//! The `radiosity` command line: clap parses the flags ([`cli`]), each
//! subcommand's flags become a checked job in one place
//! ([`cli::Cli::into_job`]), and `main` only dispatches the job to its
//! command ([`commands`], [`frames`]) and prints every error with its whole
//! context chain and a non-zero exit code.

use clap::Parser;
use cli::{Cli, Job};
use std::process::ExitCode;

mod cli;
mod commands;
mod frames;
mod outputs;

fn main() -> ExitCode {
    match Cli::parse().into_job().and_then(run) {
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

/// The job's command.
fn run(job: Job) -> anyhow::Result<()> {
    use commands as c;
    match job {
        Job::Devices { json } => c::devices(json),
        Job::Info { path, json } => c::info(&path, json),
        Job::Bake { config, json } => c::bake(config, json),
        Job::Render(job) => frames::render(job),
        Job::View(job) => frames::view(job),
        Job::Generate(job) => c::generate(job),
        Job::ExportMitsuba(job) => c::export_mitsuba(job),
        Job::Accuracy(job) => c::bench_accuracy(job),
        Job::Stress { patches, selection } => c::bench_stress(patches, selection),
        Job::Skips(options) => c::bench_skips(options),
        Job::Sweep(options) => c::bench_sweep(options),
        Job::Frame(job) => c::bench_frame(job),
        Job::Probes(job) => c::bench_probes(job),
        Job::Voxelize {
            scene,
            voxel_sizes,
            repeat,
            selection,
        } => c::bench_voxelize(&scene, &voxel_sizes, repeat, selection),
        Job::FormFactors {
            scene,
            patches,
            options,
            cpu_reference,
            selection,
        } => c::bench_form_factors(&scene, &patches, &options, cpu_reference, selection),
        Job::Solve {
            scene,
            patches,
            selection,
        } => c::bench_solve(&scene, &patches, selection),
        Job::Transfer {
            gemm_sizes,
            stress_sizes,
            rooms,
            albedos,
            selection,
        } => c::bench_transfer(&gemm_sizes, &stress_sizes, rooms, &albedos, selection),
        Job::Compression(job) => c::bench_compression(job),
    }
}
