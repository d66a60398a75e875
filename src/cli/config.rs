//! Each subcommand's flags → a validated config, in one place (after
//! ripgrep's `flags` → `HiArgs`): every check that needs only the flags
//! (ranges, names, combinations, the OpenCL device selection and its
//! environment variable, the bundled scenes a benchmark lists) runs here,
//! before any work, and its message names the flag. What the commands
//! check later needs the file system or the loaded files: outputs that
//! would overwrite an input, places that cannot take an output, a camera
//! inside no scene.

use super::args::{
    BakeArgs, BenchCommand, Cli, Command, DeviceArgs, RenderArgs, SweepArgs, ViewArgs,
};
use crate::outputs::{self, ImageFormat};
use anyhow::{bail, Context as _};
use radiosity::bake::error::BakeError;
use radiosity::bake::form_factor::{FormFactorMethod, FormFactorOptions};
use radiosity::bake::reorder::ReorderMethod;
use radiosity::bake::transfer::{InfiniteMethod, TransferOptions};
use radiosity::bake::voxelize::Resolution;
use radiosity::bake::{BakeConfig, CodecChoice, ComputeChoice};
use radiosity::bakefile::codec::CodecKind;
use radiosity::bench;
use radiosity::bench::sweep::{SweepOptions, SweepScene};
use radiosity::core::compute::DeviceSelection;
use radiosity::runtime::render::View;
use radiosity::viewer::keys::KeyScript;
use radiosity::viewer::PatchLight;
use std::path::{Path, PathBuf};

/// A command line, checked: what `main` dispatches.
pub(crate) enum Job {
    Devices {
        json: bool,
    },
    Info {
        path: PathBuf,
        json: bool,
    },
    Bake {
        config: BakeConfig,
        json: bool,
    },
    Render(RenderJob),
    View(ViewJob),
    Generate(GenerateJob),
    ExportMitsuba(ExportJob),
    Accuracy(AccuracyJob),
    Stress {
        patches: usize,
        selection: DeviceSelection,
    },
    Skips(bench::skips::SkipsOptions),
    Sweep(SweepOptions),
    Frame(FrameJob),
    Probes(ProbesJob),
    Voxelize {
        scene: PathBuf,
        voxel_sizes: Vec<f64>,
        repeat: usize,
        selection: DeviceSelection,
    },
    FormFactors {
        scene: PathBuf,
        patches: Vec<usize>,
        options: radiosity::bake::form_factor::FormFactorOptions,
        cpu_reference: bool,
        selection: DeviceSelection,
    },
    Solve {
        scene: PathBuf,
        patches: Vec<usize>,
        selection: DeviceSelection,
    },
    Transfer {
        gemm_sizes: Vec<usize>,
        stress_sizes: Vec<usize>,
        rooms: usize,
        albedos: Vec<f64>,
        selection: DeviceSelection,
    },
    Compression(CompressionJob),
}

/// `render`, checked: the raw paths and counts with the parsed view,
/// backend, shadow budget and image format.
pub(crate) struct RenderJob {
    pub(crate) args: RenderArgs,
    pub(crate) view: View,
    /// The shadow maps' budget in bytes (`None`: the renderer's default).
    pub(crate) budget: Option<u64>,
    pub(crate) format: ImageFormat,
}

/// `view`, checked.
pub(crate) struct ViewJob {
    pub(crate) args: ViewArgs,
    pub(crate) patch_light: PatchLight,
    pub(crate) budget: Option<u64>,
    pub(crate) keys: KeyScript,
    /// `--headless-to`'s format, when given.
    pub(crate) headless_format: Option<ImageFormat>,
}

/// `generate`: list the scenes, or write one into a directory.
pub(crate) enum GenerateJob {
    List,
    Write { name: String, dir: PathBuf },
}

/// `export-mitsuba`.
pub(crate) struct ExportJob {
    pub(crate) scene: PathBuf,
    pub(crate) output: PathBuf,
    pub(crate) camera_lights: Option<PathBuf>,
    pub(crate) options: radiosity::mitsuba::ExportOptions,
}

/// `bench accuracy`.
pub(crate) struct AccuracyJob {
    pub(crate) bake: PathBuf,
    pub(crate) camera_lights: Option<PathBuf>,
    pub(crate) paths: usize,
    pub(crate) points: usize,
    /// The device for the first-reflection comparison (`--first-reflection`).
    pub(crate) first_reflection: Option<DeviceSelection>,
    pub(crate) json: bool,
    pub(crate) per_patch: Option<PathBuf>,
    pub(crate) near_field: bool,
}

/// `bench frame`.
pub(crate) struct FrameJob {
    pub(crate) bake: PathBuf,
    pub(crate) camera_lights: Option<PathBuf>,
    pub(crate) options: bench::frame::FrameBenchOptions,
}

/// `bench probes`.
pub(crate) struct ProbesJob {
    pub(crate) bake: PathBuf,
    pub(crate) camera_lights: Option<PathBuf>,
    pub(crate) options: bench::probes::ProbeBenchOptions,
}

/// `bench compression`: the scenes each with its patch count.
pub(crate) struct CompressionJob {
    pub(crate) scenes: Vec<(PathBuf, usize)>,
    pub(crate) options: bench::compression::CompressionOptions,
    pub(crate) output: Option<PathBuf>,
}

impl Cli {
    /// The command line's job, every flag checked.
    pub(crate) fn into_job(self) -> anyhow::Result<Job> {
        Ok(match self.command {
            Command::Devices { json } => Job::Devices { json },
            Command::Info { path, json } => Job::Info { path, json },
            Command::Bake(args) => {
                let (config, json) = args.into_config()?;
                bake_outputs(&config)?;
                Job::Bake { config, json }
            }
            Command::Render(args) => Job::Render(render(args)?),
            Command::View(args) => Job::View(view(args)?),
            Command::Generate { name, output, list } => Job::Generate(if list {
                GenerateJob::List
            } else {
                let name = name.context("a scene name is required (see --list)")?;
                let dir = output.unwrap_or_else(|| PathBuf::from("scenes").join(&name));
                GenerateJob::Write { name, dir }
            }),
            Command::ExportMitsuba {
                scene,
                output,
                camera_lights,
                width,
                height,
                two_sided,
            } => Job::ExportMitsuba(ExportJob {
                scene,
                output,
                camera_lights,
                options: radiosity::mitsuba::ExportOptions {
                    width,
                    height,
                    two_sided,
                },
            }),
            Command::Bench { which } => bench_job(which)?,
        })
    }
}

/// A `bench` subcommand's job.
fn bench_job(which: BenchCommand) -> anyhow::Result<Job> {
    Ok(match which {
        BenchCommand::Accuracy {
            bake,
            camera_lights,
            paths,
            points,
            first_reflection,
            json,
            per_patch,
            no_near_field,
            device,
        } => {
            if paths == 0 {
                bail!("--paths must be at least 1");
            }
            Job::Accuracy(AccuracyJob {
                bake,
                camera_lights,
                paths,
                points,
                first_reflection: if first_reflection {
                    Some(selection(device)?)
                } else {
                    None
                },
                json,
                per_patch,
                near_field: !no_near_field,
            })
        }
        BenchCommand::Stress { patches, device } => {
            if patches == 0 {
                bail!("--patches must be at least 1");
            }
            Job::Stress {
                patches,
                selection: selection(device)?,
            }
        }
        BenchCommand::Skips {
            scenes,
            patches,
            repeat,
            output,
            device,
        } => Job::Skips(skips(scenes, patches, repeat, output, device)?),
        BenchCommand::Sweep(args) => Job::Sweep(sweep(args)?),
        BenchCommand::Frame {
            bake,
            camera_lights,
            repeat,
            width,
            height,
            no_classic,
            device,
        } => {
            if repeat == 0 {
                bail!("--repeat must be at least 1");
            }
            check_image_size(width, height)?;
            Job::Frame(FrameJob {
                bake,
                camera_lights,
                options: bench::frame::FrameBenchOptions {
                    repeat,
                    width,
                    height,
                    selection: selection(device)?,
                    classic: !no_classic,
                },
            })
        }
        BenchCommand::Probes {
            bake,
            camera_lights,
            probes,
            spp,
            paths,
        } => {
            if spp < 2 || spp % 2 != 0 {
                bail!("--spp {spp}: must be even and at least 2");
            }
            if probes == 0 {
                bail!("--probes must be at least 1");
            }
            Job::Probes(ProbesJob {
                bake,
                camera_lights,
                options: bench::probes::ProbeBenchOptions { probes, spp, paths },
            })
        }
        BenchCommand::Voxelize {
            scene,
            voxel_sizes,
            repeat,
            device,
        } => {
            if repeat == 0 {
                bail!("--repeat must be at least 1");
            }
            Job::Voxelize {
                scene,
                voxel_sizes,
                repeat,
                selection: selection(device)?,
            }
        }
        BenchCommand::FormFactors {
            scene,
            patches,
            method,
            rays_per_patch,
            no_cpu_reference,
            device,
        } => Job::FormFactors {
            scene,
            patches,
            options: {
                let options = radiosity::bake::form_factor::FormFactorOptions {
                    method,
                    rays_per_patch,
                    ..Default::default()
                };
                options.validate()?;
                options
            },
            cpu_reference: !no_cpu_reference,
            selection: selection(device)?,
        },
        BenchCommand::Solve {
            scene,
            patches,
            device,
        } => Job::Solve {
            scene,
            patches,
            selection: selection(device)?,
        },
        BenchCommand::Transfer {
            gemm_sizes,
            stress_sizes,
            rooms,
            albedos,
            device,
        } => Job::Transfer {
            gemm_sizes,
            stress_sizes,
            rooms,
            albedos,
            selection: selection(device)?,
        },
        BenchCommand::Compression {
            scenes,
            patches,
            reorder,
            codecs,
            lights,
            seed,
            output,
            device,
        } => {
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
                selection: selection(device)?,
            };
            Job::Compression(CompressionJob {
                scenes: scenes.into_iter().zip(patches).collect(),
                options,
                output,
            })
        }
    })
}

/// `--device`, or `RADIOSITY_CL_DEVICE` when it is not given.
fn selection(device: DeviceArgs) -> anyhow::Result<DeviceSelection> {
    Ok(DeviceSelection::from_flag_or_env(device.device)?)
}

impl BakeArgs {
    /// Raw flags → validated config.
    pub(crate) fn into_config(self) -> anyhow::Result<(BakeConfig, bool)> {
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
        let mut form_factor = FormFactorOptions::default();
        if let Some(m) = &self.form_factors {
            form_factor.method = FormFactorMethod::parse(m)
                .with_context(|| format!("--form-factors {m:?}: expected rays or contour"))?;
        }
        if let Some(r) = self.ff_rays_per_patch {
            form_factor.rays_per_patch = r;
        }
        if let Some(m) = self.ff_samples {
            form_factor.samples = m;
        }
        if let Some(r) = self.ff_rays {
            form_factor.rays = r;
        }
        let mut transfer = TransferOptions {
            bounces: self.bounces.unwrap_or_default(),
            ..TransferOptions::default()
        };
        if let Some(m) = &self.infinite_by {
            transfer.infinite = InfiniteMethod::parse(m)
                .with_context(|| format!("--infinite-by {m:?}: expected solve or doubling"))?;
        }
        let codec = match (self.max_error, self.codec, self.top_fraction) {
            (Some(e), _, _) => CodecChoice::MaxError(e),
            (None, None, None) => CodecChoice::default(),
            (None, name, top) => {
                let mut kind = match name {
                    Some(n) => CodecKind::parse(&n).context("option --codec")?,
                    None => CodecKind::default(),
                };
                if let Some(f) = top {
                    kind = kind
                        .with_top_fraction(f)
                        .with_context(|| format!("--top-fraction {f} with --codec {kind}"))?;
                }
                CodecChoice::Fixed(kind)
            }
        };
        let reorder = self
            .reorder
            .as_deref()
            .map(ReorderMethod::parse)
            .transpose()
            .map_err(with_flag)?;
        let config = BakeConfig {
            scene: self.scene,
            resolution,
            compute,
            form_factor,
            transfer,
            reorder,
            codec,
            error_lights: self.error_lights,
            two_sided: self.two_sided,
            as_wound: self.as_wound,
            near_field_rays: self.near_field_rays,
            near_field_min_form_factor: self.near_field_min_form_factor,
            probes: radiosity::bake::probes::ProbeOptions {
                spacing: match self.probe_spacing.trim() {
                    "auto" => radiosity::bake::probes::ProbeSpacing::Auto,
                    v => radiosity::bake::probes::ProbeSpacing::Voxels(v.parse().map_err(|_| {
                        anyhow::anyhow!(
                            "--probe-spacing {v:?}: expected auto or a number of voxels (0: no probes)"
                        )
                    })?),
                },
                rays: self.probe_rays,
            },
            output: self.output,
            export: self.export,
        };
        config.validate().map_err(with_flag)?;
        Ok((config, self.json))
    }
}

/// `-o` is not one of the files `--export` writes.
fn bake_outputs(config: &BakeConfig) -> anyhow::Result<()> {
    if let (Some(dir), Some(out)) = (&config.export, &config.output) {
        let files: Vec<PathBuf> = radiosity::bake::export::FILES
            .iter()
            .map(|f| dir.join(f))
            .collect();
        if files.iter().any(|f| f == out) {
            bail!(
                "-o {} is one of the files --export writes into {}",
                out.display(),
                dir.display()
            );
        }
    }
    Ok(())
}

/// The command-line flag that sets a library option (library messages name
/// options, not flags).
pub(crate) fn flag_of(option: &str) -> Option<&'static str> {
    Some(match option {
        "voxel size" => "--voxel-size",
        "patch count" => "--patches",
        "maximum codec error" => "--max-error",
        "error lights" => "--error-lights",
        "reordering" | "greedy reordering passes" => "--reorder",
        "form-factor samples per side" => "--ff-samples",
        "form-factor rays per pair" => "--ff-rays",
        "form-factor rays per patch" => "--ff-rays-per-patch",
        "near-field rays per patch" => "--near-field-rays",
        "near-field minimum form factor" => "--near-field-min-form-factor",
        "probe spacing in voxels" => "--probe-spacing",
        "rays per probe" => "--probe-rays",
        "bounces" => "--bounces",
        _ => return None,
    })
}

/// A bake error, with the flag of the option at fault named.
pub(crate) fn with_flag(e: BakeError) -> anyhow::Error {
    match e.option().and_then(flag_of) {
        Some(flag) => anyhow::Error::new(e).context(format!("option {flag}")),
        None => e.into(),
    }
}

/// `render`'s flags.
fn render(args: RenderArgs) -> anyhow::Result<RenderJob> {
    let view = View::parse(&args.view).with_context(|| {
        format!(
            "--view {:?}: expected final, direct, indirect, patches or weights",
            args.view
        )
    })?;
    if !matches!(args.backend.as_str(), "cpu" | "gl" | "auto") {
        bail!("--backend {:?}: expected cpu, gl or auto", args.backend);
    }
    check_shadow_resolution(args.shadow_resolution)?;
    check_samples(args.samples)?;
    check_cull(args.cull)?;
    check_exposure(args.exposure)?;
    check_image_size(args.width, args.height)?;
    let budget = shadow_budget(args.shadow_budget)?;
    // The outputs' formats by their names.
    let format = ImageFormat::of(&args.output, "-o")?;
    if let Some(hdr) = &args.hdr {
        outputs::check_pfm(hdr, "--hdr")?;
    }
    Ok(RenderJob {
        args,
        view,
        budget,
        format,
    })
}

/// `view`'s flags.
fn view(args: ViewArgs) -> anyhow::Result<ViewJob> {
    check_samples(args.samples)?;
    check_cull(args.cull)?;
    check_shadow_resolution(args.shadow_resolution)?;
    if !(1..=16384).contains(&args.width) || !(1..=16384).contains(&args.height) {
        bail!(
            "--width {} --height {}: expected 1..=16384 each",
            args.width,
            args.height
        );
    }
    check_exposure(args.exposure)?;
    let patch_light = PatchLight::parse(&args.patch_light).with_context(|| {
        format!(
            "--patch-light {:?}: expected gpu, cpu or auto",
            args.patch_light
        )
    })?;
    if args.frames == Some(0) {
        bail!("--frames 0: expected at least 1");
    }
    let budget = shadow_budget(args.shadow_budget)?;
    let keys = KeyScript::parse(args.keys.as_deref().unwrap_or(""))
        .with_context(|| format!("--keys {:?}", args.keys.as_deref().unwrap_or("")))?;
    if let Some(n) = args.frames.filter(|&n| n <= keys.len() as u64) {
        bail!(
            "--frames {n} with {} key presses: one press follows each frame, so at least {} frames",
            keys.len(),
            keys.len() + 1
        );
    }
    if args.screenshot.is_some() && args.frames.is_none() {
        bail!("--screenshot needs --frames N (P or F12 saves screenshots interactively)");
    }
    if let Some(p) = &args.screenshot {
        ImageFormat::of(p, "--screenshot")?;
    }
    let headless_format = match &args.headless_to {
        Some(p) => Some(ImageFormat::of(p, "--headless-to")?),
        None => None,
    };
    Ok(ViewJob {
        args,
        patch_light,
        budget,
        keys,
        headless_format,
    })
}

/// `--samples`: 1 to 16 per pixel.
fn check_samples(samples: usize) -> anyhow::Result<()> {
    if !(1..=16).contains(&samples) {
        bail!("--samples {samples}: expected 1..=16");
    }
    Ok(())
}

/// `--shadow-resolution`: 16 to the renderer's largest map.
fn check_shadow_resolution(r: usize) -> anyhow::Result<()> {
    let max = radiosity::gl::shadow::MAX_RESOLUTION;
    if !(16..=max).contains(&r) {
        bail!("--shadow-resolution {r}: expected 16..={max}");
    }
    Ok(())
}

/// An image of `width × height` pixels must have between 1 and 2^26
/// (8192²: 0.8 GB of linear radiance), the product taken without overflow.
fn check_image_size(width: usize, height: usize) -> anyhow::Result<()> {
    match width.checked_mul(height) {
        Some(p) if (1..=1 << 26).contains(&p) => Ok(()),
        _ => bail!(
            "--width {width} --height {height}: the image must have between 1 and 2^26 pixels"
        ),
    }
}

/// `--shadow-budget` in MiB as bytes: positive, finite and at most 2^24
/// MiB (16 TiB).
fn shadow_budget(mib: Option<f64>) -> anyhow::Result<Option<u64>> {
    match mib {
        None => Ok(None),
        Some(m) if m.is_finite() && m > 0.0 && m <= (1u64 << 24) as f64 => {
            Ok(Some((m * (1u64 << 20) as f64).round().max(1.0) as u64))
        }
        Some(m) => bail!("--shadow-budget {m}: expected a positive number of MiB, at most 2^24"),
    }
}

/// A fixed exposure must scale radiance to something displayable: a
/// positive finite factor (NaN or infinity would write a black or white
/// image without a word).
fn check_exposure(exposure: Option<f32>) -> anyhow::Result<()> {
    match exposure {
        Some(e) if !(e.is_finite() && e > 0.0) => {
            bail!("--exposure {e}: expected a positive finite factor")
        }
        _ => Ok(()),
    }
}

/// `--cull`: a fraction in [0, 1) (NaN refused).
fn check_cull(cull: f64) -> anyhow::Result<()> {
    if !(0.0..1.0).contains(&cull) {
        bail!("--cull {cull}: expected a fraction in [0, 1)");
    }
    Ok(())
}

/// `bench sweep`'s flags → its options.
fn sweep(a: SweepArgs) -> anyhow::Result<SweepOptions> {
    let selection = selection(a.device)?;
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
            // And under the sun and sky (issue 43).
            scenes.extend(sponza_lit_by("sponza_noon.json"));
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
                .map(|c| CodecKind::parse(c))
                .collect::<Result<_, _>>()?,
            reorders: vec![ReorderMethod::None, ReorderMethod::SpaceFillingCurve],
            repeat: a.repeat,
            gl: !a.no_gl,
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
            .map(|s| CodecKind::parse(s).with_context(|| format!("--codecs {s:?}")))
            .collect::<anyhow::Result<_>>()?;
    }
    if !a.reorders.is_empty() {
        options.reorders = a
            .reorders
            .iter()
            .map(|r| ReorderMethod::parse(r).with_context(|| format!("--reorders {r:?}")))
            .collect::<anyhow::Result<_>>()?;
    }
    if a.quick {
        options.repeat = a.repeat.min(2);
        options.gl = !a.no_gl;
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
    Ok(options)
}

/// `bench skips`' flags → its options.
fn skips(
    scenes: Vec<String>,
    patches: usize,
    repeat: usize,
    output: PathBuf,
    device: DeviceArgs,
) -> anyhow::Result<bench::skips::SkipsOptions> {
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
            list.push(SweepScene {
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
    Ok(bench::skips::SkipsOptions {
        scenes: list,
        patches,
        repeat,
        selection: selection(device)?,
        out: output,
    })
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

/// A scene argument of the benchmarks: SCENE.obj (lights in SCENE.json)
/// or SCENE.obj=LIGHTS.json.
fn bench_scene(s: &str) -> anyhow::Result<SweepScene> {
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
    Ok(SweepScene {
        obj,
        camera_lights: json,
    })
}

/// Sponza by path with its camera and lights, when present.
fn sponza_scene() -> Option<SweepScene> {
    sponza_lit_by("sponza.json")
}

/// Sponza by path with the camera and lights `external/NAME` of the
/// bundled scenes, when present.
fn sponza_lit_by(name: &str) -> Option<SweepScene> {
    let sponza = PathBuf::from("../shared/scenes/sponza/sponza.obj");
    let lights = bundled_scene_path("cornell_box")
        .ok()?
        .parent()
        .and_then(|p| p.parent())
        .map(|p| p.join("external").join(name))?;
    sponza.exists().then_some(SweepScene {
        obj: sponza,
        camera_lights: lights,
    })
}
