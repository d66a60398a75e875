//! The `radiosity` command line. Flags are parsed by clap into raw structs,
//! turned into validated config structs from the library, and every error
//! is printed with its whole context chain and a non-zero exit code.

use anyhow::{bail, Context as _};
use clap::{Args, Parser, Subcommand};
use radiosity::bake::error::BakeError;
use radiosity::bake::form_factor::{FormFactorMethod, FormFactorOptions};
use radiosity::bake::reorder::ReorderMethod;
use radiosity::bake::transfer::{Bounces, InfiniteMethod, TransferOptions};
use radiosity::bake::voxelize::Resolution;
use radiosity::bake::{self, BakeConfig, CodecChoice, ComputeChoice};
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
mod reports;

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
    /// Describe a scene (.obj: triangles, materials, bounds, areas, repairs)
    /// or a bake file (.rad: patches, bounces, codec, bytes per entry).
    Info {
        /// The scene or bake file (told apart by the bake file's magic).
        path: PathBuf,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Bake a scene: voxelize, form factors, transfer matrix, reorder,
    /// compress, mesh-to-patch map, write the .rad file (-o), report.
    Bake(BakeArgs),
    /// Render a view of a bake (or of a scene, baked first or taken from the
    /// bake cache) on the CPU or headless on GL: direct light with shadows,
    /// indirect light from the compressed matrix through the surface map,
    /// tone mapped to an sRGB PNG (and optionally the linear radiance as
    /// PFM).
    Render(RenderArgs),
    /// Open a window on a bake (or a scene, baked first or taken from the
    /// bake cache): move the camera and the lights and watch indirect light
    /// follow (keys: H). Needs a display; `render` draws the same headless.
    View(ViewArgs),
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
    /// Write a scene with its camera, lights and emission scales as a
    /// Mitsuba 3 scene (scene.xml, lights_only.xml, meshes, linear textures)
    /// for independent reference images (scripts/mitsuba-reference).
    ExportMitsuba {
        /// The scene (.obj).
        scene: PathBuf,
        /// Output directory.
        #[arg(short, long)]
        output: PathBuf,
        /// The camera and lights (default: the scene's NAME.json beside it).
        #[arg(long, value_name = "FILE.json")]
        camera_lights: Option<PathBuf>,
        #[arg(long, default_value_t = 640)]
        width: usize,
        #[arg(long, default_value_t = 480)]
        height: usize,
        /// Surfaces reflect on both sides (as a --two-sided bake).
        #[arg(long)]
        two_sided: bool,
    },
    /// Benchmarks (time with error against a named reference).
    Bench {
        #[command(subcommand)]
        which: BenchCommand,
    },
}

#[derive(Subcommand)]
enum BenchCommand {
    /// Numerical stability on generated scenes that are not kind: scales
    /// 1e-3 to 1e4, the furnace at albedo 0.9 and 0.99 (exact E/(1-ρ)),
    /// near-coincident surfaces, a wall thinner than a voxel; H against the
    /// exact f64 solution of the same F; fails on any non-finite value.
    Stress {
        /// Target patch count of each bake.
        #[arg(long, default_value_t = 600)]
        patches: usize,
        #[command(flatten)]
        device: DeviceArgs,
    },
    /// What each scene does not need (patches, pairs, zero tiles, identical
    /// channels, zero columns, unchanged frames) and what skipping it
    /// saves, measured by turning each off in the same run.
    Skips {
        /// Scenes: SCENE.obj or SCENE.obj=LIGHTS.json (default: the Cornell
        /// box, the interior, the closed cube, and Sponza when present).
        #[arg(long, value_delimiter = ',')]
        scenes: Vec<String>,
        /// Target patch count of each bake.
        #[arg(long, default_value_t = 2000)]
        patches: usize,
        #[arg(long, default_value_t = 3)]
        repeat: usize,
        /// The report's directory.
        #[arg(short, long, default_value = "docs/skips")]
        output: PathBuf,
        #[command(flatten)]
        device: DeviceArgs,
    },
    /// Run time against error over scenes, patch counts, bounces, codecs
    /// and reorderings, with classic radiosity and the GL frame in the same
    /// run: sweep.json, sweep.md and log-log Pareto plots (SVG) in -o DIR.
    /// Fails when a value is non-finite or a baseline error exceeds its
    /// bound. --quick is the CI sweep (the Cornell box, a few minutes).
    Sweep {
        /// The CI sweep: the Cornell box at 256 and 1,000 patches, 1 and 3
        /// bounces, BC1 without its sparse part, no reordering.
        #[arg(long)]
        quick: bool,
        /// Scenes: SCENE.obj (camera and lights in SCENE.json beside it) or
        /// SCENE.obj=LIGHTS.json (default: the Cornell box, the interior,
        /// and ../shared/scenes/sponza/sponza.obj when present).
        #[arg(long, value_delimiter = ',')]
        scenes: Vec<String>,
        /// Patch counts (default 500,2000,4000).
        #[arg(long, value_delimiter = ',')]
        patches: Vec<usize>,
        /// Bounce counts besides the baseline's ∞ (default 1,2,3).
        #[arg(long, value_delimiter = ',')]
        bounces: Vec<u32>,
        /// Fixed codecs besides the baseline's choice, separated by ';'
        /// (default "bc1:top=0;bc4;bc6h;f16").
        #[arg(long)]
        codecs: Option<String>,
        /// Reorderings besides the default (default none,hilbert).
        #[arg(long, value_delimiter = ',')]
        reorders: Vec<String>,
        #[arg(long, default_value_t = 3)]
        repeat: usize,
        /// Leave out the GL frame.
        #[arg(long)]
        no_gl: bool,
        /// Only the baseline bakes (no bounce, codec or reordering
        /// variants).
        #[arg(long)]
        baseline_only: bool,
        /// The report's directory.
        #[arg(short, long, default_value = "docs/sweep")]
        output: PathBuf,
        /// The bound on a baseline point's relative RMS error of H.
        #[arg(long, default_value_t = 0.05, allow_negative_numbers = true)]
        max_error: f64,
        /// The bound on a baseline point's indirect image error against
        /// Mitsuba 3 (noise removed).
        #[arg(long, default_value_t = 0.5, allow_negative_numbers = true)]
        max_image_error: f64,
        /// Leave out the image errors against Mitsuba 3.
        #[arg(long)]
        no_images: bool,
        /// Where the Mitsuba 3 references are, one folder per scene stem;
        /// a missing one is made by scripts/mitsuba-reference (default:
        /// OUTPUT/reference).
        #[arg(long, value_name = "DIR")]
        references: Option<PathBuf>,
        /// Size of the reference images, WxH (default 320x240; quick
        /// 160x120).
        #[arg(long, value_name = "WxH")]
        reference_size: Option<String>,
        /// Samples per pixel of a reference made by the sweep (default
        /// 1024; quick 512).
        #[arg(long)]
        reference_spp: Option<u32>,
        #[command(flatten)]
        device: DeviceArgs,
    },
    /// A bake's patch irradiance against an independent Monte Carlo path
    /// tracer on the original triangles (bias, relative RMS, the first
    /// reflection and later bounces, form-factor row sums).
    Accuracy {
        /// The bake file.
        bake: PathBuf,
        /// The camera and lights (default: the scene's NAME.json).
        #[arg(long, value_name = "FILE.json")]
        camera_lights: Option<PathBuf>,
        /// Paths per sample point.
        #[arg(long, default_value_t = 128)]
        paths: usize,
        /// Sample points per patch (1..=16), for the reference and for the
        /// bake's direct light alike. All 16 by default: a patch's points
        /// measure its mean over a region whose light varies (sun and
        /// shadow), and 4 points leave that spatial sampling in the measure.
        #[arg(long, default_value_t = 16)]
        points: usize,
        /// Also measure the first reflection (recomputes F).
        #[arg(long)]
        first_reflection: bool,
        /// Print JSON.
        #[arg(long)]
        json: bool,
        /// Also write one CSV row per patch (centre, normal, area, H, the
        /// reference and its standard error, B0, D) to this file.
        #[arg(long, value_name = "FILE.csv")]
        per_patch: Option<PathBuf>,
        /// Leave out the bake's near-field correction (to measure what it
        /// does).
        #[arg(long)]
        no_near_field: bool,
        #[command(flatten)]
        device: DeviceArgs,
    },
    /// The CPU run time's frame stage by stage (direct, gather with and
    /// without column skipping, unchanged frame, render), the gather's
    /// bandwidth against a triad measured in the same run, and classic
    /// radiosity (k dense f32 passes over F, and Jacobi to the same error)
    /// on the same patches.
    Frame {
        /// The bake file.
        bake: PathBuf,
        /// The camera and lights (default: the scene's NAME.json).
        #[arg(long, value_name = "FILE.json")]
        camera_lights: Option<PathBuf>,
        /// Repetitions per measurement (the fastest is reported).
        #[arg(long, default_value_t = 5)]
        repeat: usize,
        #[arg(long, default_value_t = 640)]
        width: usize,
        #[arg(long, default_value_t = 480)]
        height: usize,
        /// Skip the classic baseline (it recomputes F).
        #[arg(long)]
        no_classic: bool,
        #[command(flatten)]
        device: DeviceArgs,
    },
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
    /// T_inf of a real scene by the LU solve and by doubling, against the
    /// f64 solve (one channel, R), after the bake's first stages.
    Solve {
        /// The scene (OBJ).
        scene: PathBuf,
        /// Comma-separated patch targets.
        #[arg(long, value_delimiter = ',', default_value = "4000")]
        patches: Vec<usize>,
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
    /// Compression report (docs/compression.md): every reordering × codec
    /// on each scene's T_∞, errors of T̃ and of H = T̃·B0 over seeded
    /// random lights, bytes per entry and times, as Markdown.
    Compression {
        /// The scene files (.obj).
        #[arg(required = true)]
        scenes: Vec<PathBuf>,
        /// Target patch counts: one for every scene, or one per scene
        /// (comma-separated, in the scenes' order).
        #[arg(long, value_delimiter = ',', default_value = "2000")]
        patches: Vec<usize>,
        /// Comma-separated reorderings: none, greedy:PASSES, hilbert.
        #[arg(long, value_delimiter = ',', default_value = "none,greedy:1,greedy:2,hilbert",
              value_parser = |s: &str| radiosity::bake::reorder::ReorderMethod::parse(s).map_err(|e| e.to_string()))]
        reorder: Vec<radiosity::bake::reorder::ReorderMethod>,
        /// A codec (repeat the flag, or separate with `;`): f32, f16, bc6h,
        /// bc1/bc4 with options (e.g. `bc1:top=0.02,L=auto,sparse=f16`),
        /// `thesis` or `default`. Default: the report's eight settings.
        #[arg(long = "codec", value_delimiter = ';',
              value_parser = |s: &str| bench::compression::parse_report_codec(s).map_err(|e| e.to_string()))]
        codecs: Vec<radiosity::bakefile::codec::CodecKind>,
        /// Seeded random lights (each one B0 sample).
        #[arg(long, default_value_t = 64)]
        lights: usize,
        /// Seed of the random lights.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Write the Markdown to this file (atomically) instead of stdout.
        #[arg(short, long)]
        output: Option<PathBuf>,
        #[command(flatten)]
        device: DeviceArgs,
    },
}

#[derive(Args)]
struct RenderArgs {
    /// A bake file (.rad), or a scene (.obj) to bake first (or reuse from
    /// the bake cache: $RADIOSITY_CACHE_DIR, else ~/.cache/radiosity).
    input: PathBuf,
    /// The PNG to write.
    #[arg(short, long, value_name = "OUT.png")]
    output: PathBuf,
    /// What to show: final, direct, indirect or patches (radiances), or
    /// weights (the surface map: each patch a colour, blended by weight).
    #[arg(long, default_value = "final")]
    view: String,
    /// The camera and lights (default: the scene's NAME.json beside it).
    #[arg(long, value_name = "FILE.json")]
    camera_lights: Option<PathBuf>,
    /// The scene the bake was made from, for geometry and textures (default:
    /// the one the bake file names, relative to the bake file).
    #[arg(long, value_name = "SCENE.obj")]
    scene: Option<PathBuf>,
    #[arg(long, default_value_t = 640)]
    width: usize,
    #[arg(long, default_value_t = 480)]
    height: usize,
    /// cpu (the reference renderer: ray casting), gl (OpenGL 4.5 through
    /// EGL, headless: shadow maps, the gather in a compute shader), or auto
    /// (gl on a GPU; cpu where GL is software, such as llvmpipe, or no
    /// context can be made).
    #[arg(long, default_value = "cpu")]
    backend: String,
    /// Shadow map side in texels (gl).
    #[arg(long, default_value_t = 2048)]
    shadow_resolution: usize,
    /// The most GPU memory the shadow maps may take, in MiB (gl; default:
    /// what the GL grants). Lights needing more are refused with the sizes.
    #[arg(long, value_name = "MIB")]
    shadow_budget: Option<f64>,
    /// Also write the view's linear radiance, before exposure, as PFM.
    #[arg(long, value_name = "OUT.pfm")]
    hdr: Option<PathBuf>,
    /// Exposure (default: automatic, 0.18 over the log-average luminance).
    #[arg(long, allow_negative_numbers = true)]
    exposure: Option<f32>,
    /// Sample points per patch for direct light (1..=16).
    #[arg(long, default_value_t = radiosity::runtime::direct::DEFAULT_SAMPLES)]
    samples: usize,
    /// Target patch count when baking a scene.
    #[arg(long, default_value_t = 2000)]
    patches: usize,
    #[command(flatten)]
    device: DeviceArgs,
}

#[derive(Args)]
struct ViewArgs {
    /// A bake file (.rad), or a scene (.obj) to bake first (or reuse from
    /// the bake cache).
    input: PathBuf,
    /// The camera and lights (default: the scene's NAME.json beside it).
    #[arg(long, value_name = "FILE.json")]
    camera_lights: Option<PathBuf>,
    /// Where F5 / Ctrl+S saves the camera and lights (default: the
    /// camera/lights file).
    #[arg(long, value_name = "FILE.json")]
    save_to: Option<PathBuf>,
    /// The scene the bake was made from (default: the one the bake file
    /// names).
    #[arg(long, value_name = "SCENE.obj")]
    scene: Option<PathBuf>,
    #[arg(long, default_value_t = 1280)]
    width: u32,
    #[arg(long, default_value_t = 720)]
    height: u32,
    /// Render this many frames, then exit (with --screenshot: save the
    /// last one).
    #[arg(long)]
    frames: Option<u64>,
    /// The PNG --frames saves.
    #[arg(long, value_name = "FILE.png")]
    screenshot: Option<PathBuf>,
    /// Exposure (default: automatic from the first frame).
    #[arg(long, allow_negative_numbers = true)]
    exposure: Option<f32>,
    /// Where each frame's patch light (direct light on the patches and the
    /// gather) runs: gpu, cpu (the CPU run time, H uploaded for the GPU's
    /// shading: for software GL such as llvmpipe), or auto (both timed on
    /// the first frame, the faster kept).
    #[arg(long, default_value = "auto")]
    patch_light: String,
    /// Where there is no display: render the starting view headless to
    /// this PNG instead (GL through EGL, else the CPU) and print its path.
    #[arg(long, value_name = "FILE.png")]
    headless_to: Option<PathBuf>,
    /// Shadow map side in texels.
    #[arg(long, default_value_t = 2048)]
    shadow_resolution: usize,
    /// The most GPU memory the shadow maps may take, in MiB (default: what
    /// the GL grants). A light added beyond it is taken back, with the
    /// sizes on stderr.
    #[arg(long, value_name = "MIB")]
    shadow_budget: Option<f64>,
    /// Keys to press, one after each drawn frame, before the user's:
    /// comma-separated names as winit gives them, each optionally `*COUNT`
    /// ("KeyB,ArrowLeft*3,F5": add a spot, move it left three steps, save).
    /// For demonstrations that repeat exactly, and for tests.
    #[arg(long, value_name = "KEYS")]
    keys: Option<String>,
    /// Sample points per patch for direct light (1..=16).
    #[arg(long, default_value_t = radiosity::runtime::direct::DEFAULT_SAMPLES)]
    samples: usize,
    /// Target patch count when baking a scene.
    #[arg(long, default_value_t = 2000)]
    patches: usize,
    #[command(flatten)]
    device: DeviceArgs,
}

#[derive(Args, Clone)]
struct DeviceArgs {
    /// OpenCL device index (see `radiosity devices`); overrides RADIOSITY_CL_DEVICE.
    #[arg(long, value_name = "INDEX")]
    pub(crate) device: Option<usize>,
}

#[derive(Args)]
struct BakeArgs {
    /// The scene (.obj with its .mtl).
    scene: PathBuf,
    /// Write the bake file (.rad) here (atomically: a temporary file, then
    /// a rename). Without it the bake runs and reports but writes nothing.
    #[arg(short, long, value_name = "OUT.rad")]
    output: Option<PathBuf>,
    /// Voxel edge length in scene units.
    #[arg(long, conflicts_with = "patches", allow_negative_numbers = true)]
    voxel_size: Option<f64>,
    /// Target patch count; the voxel size is searched for. Default 2000.
    #[arg(long)]
    patches: Option<usize>,
    /// Light bounces folded into the transfer matrix: a number k >= 1, or
    /// `inf` for the converged limit (default: inf).
    #[arg(long, value_parser = parse_bounces)]
    bounces: Option<Bounces>,
    /// Form factors: rays (from the patches' real surfaces, the default) or
    /// contour (contour integrals between patch squares).
    #[arg(long, value_name = "METHOD")]
    form_factors: Option<String>,
    /// Rays per patch of the rays method (16..=1048576, default 16384).
    #[arg(long, value_name = "N")]
    ff_rays_per_patch: Option<u32>,
    /// Rays per patch of the near-field correction (0..=65535; 0: none):
    /// the first reflection from a close neighbour uses the part of it the
    /// patch sees, not its mean (docs/accuracy.md).
    #[arg(long, value_name = "N", default_value_t = radiosity::bake::near_field::DEFAULT_RAYS)]
    near_field_rays: u32,
    /// Near-field links with a measured form factor below this (0..=1) are
    /// not stored; their light still reaches the receivers through each
    /// patch's far weights. Lower keeps more links (larger file).
    #[arg(long, value_name = "F", default_value_t = radiosity::bake::near_field::MIN_FORM_FACTOR, allow_negative_numbers = true)]
    near_field_min_form_factor: f64,
    /// Form-factor emitter samples per side, contour method (1..=16, default 4).
    #[arg(long)]
    ff_samples: Option<u32>,
    /// Form-factor visibility rays per patch pair (1..=64, default 4).
    #[arg(long)]
    ff_rays: Option<u32>,
    /// Reordering before compression: none, greedy[:PASSES] (the thesis's,
    /// O(n³)), or hilbert (space-filling curve). Default: greedy:2 up to
    /// 4096 patches, hilbert above.
    #[arg(long, value_name = "METHOD")]
    reorder: Option<String>,
    /// Codec: bc1 (the thesis's: BC1 of log-scaled entries + exact top
    /// fraction), bc4, bc6h, f16 or f32; bc1/bc4 take options, e.g.
    /// `bc1:top=0.02,L=auto,sparse=f16` (sparse values f32, f16 or rgb9e5).
    /// Default: bc1:top=0.04,L=auto,sparse=rgb9e5.
    #[arg(long, value_name = "CODEC", conflicts_with = "max_error")]
    codec: Option<String>,
    /// Fraction of the matrix entries kept in the sparse part, beside the
    /// BC texture (bc1/bc4; exact with sparse=f32, within 2^-11 with f16,
    /// within 2^-9 of the largest channel with rgb9e5;
    /// default 0.04).
    #[arg(
        long,
        value_name = "F",
        conflicts_with = "max_error",
        allow_negative_numbers = true
    )]
    top_fraction: Option<f64>,
    /// Choose the cheapest codec setting whose relative RMS error of H = T·B0
    /// over the error lights is at most E, preferring BC1/BC4 within twice
    /// its bytes (fast CPU decode); default 0.02 unless --codec or
    /// --top-fraction fixes the setting.
    #[arg(long, value_name = "E", allow_negative_numbers = true)]
    max_error: Option<f64>,
    /// Seeded random lights the compression error is measured over (0: do
    /// not measure; at most 4096).
    #[arg(long, value_name = "N", default_value_t = bake::DEFAULT_ERROR_LIGHTS)]
    error_lights: usize,
    /// Patches on both sides of every surface, for scenes whose faces are
    /// not reliably wound towards the viewer (recorded in the file; `info`
    /// shows it).
    #[arg(long)]
    two_sided: bool,
    /// T_inf by `solve` (a blocked LU solve, the default) or `doubling`
    /// (the series, doubled until it converges).
    #[arg(long, value_name = "METHOD")]
    infinite_by: Option<String>,
    /// Write inspection files (patches.csv, patches.png, F.npy, T.npy,
    /// T_decoded.npy, albedo.npy) into this directory.
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
            near_field_rays: self.near_field_rays,
            near_field_min_form_factor: self.near_field_min_form_factor,
            output: self.output,
            export: self.export,
        };
        config.validate().map_err(with_flag)?;
        Ok((config, self.json))
    }
}

/// The command-line flag that sets a library option (library messages name
/// options, not flags).
fn flag_of(option: &str) -> Option<&'static str> {
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
        "bounces" => "--bounces",
        _ => return None,
    })
}

/// A bake error, with the flag of the option at fault named.
fn with_flag(e: BakeError) -> anyhow::Error {
    match e.option().and_then(flag_of) {
        Some(flag) => anyhow::Error::new(e).context(format!("option {flag}")),
        None => e.into(),
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
    if json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        print!("{summary}");
    }
    Ok(())
}

/// `radiosity bake`.
fn bake(args: BakeArgs) -> anyhow::Result<()> {
    let (config, json) = args.into_config()?;
    let out = bake::run(&config, &mut |line| eprintln!("[bake] {line}")).map_err(|e| {
        // The library names the remedy "two-sided"; here it is a flag.
        let facing = e
            .downcast_ref::<bake::error::BakeError>()
            .is_some_and(|b| matches!(b, bake::error::BakeError::Facing { .. }));
        let e = e.context(format!("baking {}", config.scene.display()));
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
            write_atomic(&path, report.as_bytes(), None)
                .with_context(|| format!("writing {}", path.display()))?;
            eprintln!("wrote {}", path.display());
        }
        None => print!("{report}"),
    }
    Ok(())
}
