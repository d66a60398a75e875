//! The command line's flags as clap parses them: the subcommands and their
//! raw arguments, turned into checked jobs by [`super::config`].

use clap::{Args, Parser, Subcommand};
use radiosity::bake;
use radiosity::bake::transfer::Bounces;
use radiosity::bench;
use std::path::PathBuf;

#[derive(Parser)]
#[command(
    name = "radiosity",
    version,
    about = "Real-time radiosity: bake a compressed multi-bounce transfer matrix for a static diffuse scene",
    long_about = None
)]
pub(crate) struct Cli {
    #[command(subcommand)]
    pub(crate) command: Command,
}

#[derive(Subcommand)]
pub(crate) enum Command {
    /// List OpenCL platforms and devices (the index is what --device takes).
    Devices {
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Describe a scene (.obj, .gltf, .glb: triangles, materials, bounds,
    /// areas, repairs, the file's camera and lights)
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
    /// follow (the keys below; H in the window shows them). Needs a
    /// display; `render` (or --headless-to) draws the same view headless.
    #[command(after_help = view_keys())]
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
        /// The scene (.obj, .gltf or .glb).
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
pub(crate) enum BenchCommand {
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
        /// The report's directory (the committed report is docs/skips:
        /// name it to update it).
        #[arg(short, long, default_value = "out/skips")]
        output: PathBuf,
        #[command(flatten)]
        device: DeviceArgs,
    },
    /// Run time against error over scenes, patch counts, bounces, codecs
    /// and reorderings, with classic radiosity and the GL frame in the same
    /// run: sweep.json, sweep.md and log-log Pareto plots (SVG) in -o DIR.
    /// Fails when a value is non-finite or a baseline error exceeds its
    /// bound. --quick is the CI sweep (the Cornell box, a few minutes).
    Sweep(SweepArgs),
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
    /// The irradiance probes against Mitsuba 3's irradiance meter at the
    /// probes, about six directions (and our path tracer beside it).
    Probes {
        /// The bake file.
        bake: PathBuf,
        /// The camera and lights (default: the scene's NAME.json).
        #[arg(long, value_name = "FILE.json")]
        camera_lights: Option<PathBuf>,
        /// Probes compared, spread over the valid ones.
        #[arg(long, default_value_t = 24)]
        probes: usize,
        /// Mitsuba paths per probe and direction (even, ≥ 2).
        #[arg(long, default_value_t = 8192)]
        spp: usize,
        /// Our path tracer's paths per probe and direction (0: not run).
        #[arg(long, default_value_t = 4096)]
        paths: usize,
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
    /// Form factors: OpenCL and the CPU reference at several patch counts
    /// (rays: the device's traversal against the CPU's, which must agree
    /// exactly; contour: the kernel against its f64 reference).
    FormFactors {
        /// The scene file.
        scene: PathBuf,
        /// Comma-separated target patch counts.
        #[arg(long, value_delimiter = ',', required = true)]
        patches: Vec<usize>,
        /// The method benchmarked: rays (the bake's default) or contour.
        #[arg(long, default_value = "rays",
              value_parser = |s: &str| radiosity::bake::form_factor::FormFactorMethod::parse(s)
                  .ok_or_else(|| format!("unknown form-factor method {s:?}: expected rays or contour")))]
        method: radiosity::bake::form_factor::FormFactorMethod,
        /// Rays per patch of the rays method.
        #[arg(long, default_value_t = 16384)]
        rays_per_patch: u32,
        /// Skip the (slow) CPU reference.
        #[arg(long)]
        no_cpu_reference: bool,
        #[command(flatten)]
        device: DeviceArgs,
    },
    /// T_inf of a real scene by the LU solve and by doubling, against the
    /// f64 solve (one channel, R), after the bake's first stages.
    Solve {
        /// The scene (OBJ or glTF).
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
        /// The scene files (.obj, .gltf, .glb).
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
pub(crate) struct RenderArgs {
    /// A bake file (.rad), or a scene (.obj, .gltf, .glb) to bake first (or reuse from
    /// the bake cache: $RADIOSITY_CACHE_DIR, else ~/.cache/radiosity).
    pub(crate) input: PathBuf,
    /// The PNG to write.
    #[arg(short, long, value_name = "OUT.png")]
    pub(crate) output: PathBuf,
    /// What to show: final, direct, indirect or patches (radiances), or
    /// weights (the surface map: each patch a colour, blended by weight).
    #[arg(long, default_value = "final")]
    pub(crate) view: String,
    /// The camera and lights (default: the scene's NAME.json beside it).
    #[arg(long, value_name = "FILE.json")]
    pub(crate) camera_lights: Option<PathBuf>,
    /// The scene the bake was made from, for geometry and textures (default:
    /// the one the bake file names, relative to the bake file).
    #[arg(long, value_name = "SCENE")]
    pub(crate) scene: Option<PathBuf>,
    #[arg(long, default_value_t = 640)]
    pub(crate) width: usize,
    #[arg(long, default_value_t = 480)]
    pub(crate) height: usize,
    /// cpu (the reference renderer: ray casting), gl (OpenGL 4.5 through
    /// EGL, headless: shadow maps, the gather in a compute shader), or auto
    /// (gl on a GPU; cpu where GL is software, such as llvmpipe, or no
    /// context can be made).
    #[arg(long, default_value = "cpu")]
    pub(crate) backend: String,
    /// Shadow map side in texels (gl).
    #[arg(long, default_value_t = 2048)]
    pub(crate) shadow_resolution: usize,
    /// The most GPU memory the shadow maps may take, in MiB (gl; default:
    /// what the GL grants). Lights needing more are refused with the sizes.
    #[arg(long, value_name = "MIB")]
    pub(crate) shadow_budget: Option<f64>,
    /// Also write the view's linear radiance, before exposure, as PFM.
    #[arg(long, value_name = "OUT.pfm")]
    pub(crate) hdr: Option<PathBuf>,
    /// Draw the probe view: a sphere at each irradiance probe, shaded by
    /// its irradiance (the GL back end: --backend gl).
    #[arg(long)]
    pub(crate) probes: bool,
    /// Exposure (default: automatic, 0.18 over the log-average luminance).
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) exposure: Option<f32>,
    /// Sample points per patch for direct light (1..=16).
    #[arg(long, default_value_t = radiosity::runtime::direct::DEFAULT_SAMPLES)]
    pub(crate) samples: usize,
    /// Cull negligible columns of each gather (cpu): drop the columns of
    /// least weight whose bound on H's L1 norm sums to at most this
    /// fraction (0..1). 0, the default for this reference renderer: only
    /// zero columns are skipped, exact to the bit.
    #[arg(
        long,
        value_name = "EPS",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    pub(crate) cull: f64,
    /// Target patch count when baking a scene.
    #[arg(long, default_value_t = 2000)]
    pub(crate) patches: usize,
    #[command(flatten)]
    pub(crate) device: DeviceArgs,
}

#[derive(Args)]
pub(crate) struct ViewArgs {
    /// A bake file (.rad), or a scene (.obj, .gltf, .glb) to bake first (or reuse from
    /// the bake cache).
    pub(crate) input: PathBuf,
    /// The camera and lights (default: the scene's NAME.json beside it).
    #[arg(long, value_name = "FILE.json")]
    pub(crate) camera_lights: Option<PathBuf>,
    /// Where F5 / Ctrl+S saves the camera and lights (default: the
    /// camera/lights file).
    #[arg(long, value_name = "FILE.json")]
    pub(crate) save_to: Option<PathBuf>,
    /// The scene the bake was made from (default: the one the bake file
    /// names).
    #[arg(long, value_name = "SCENE")]
    pub(crate) scene: Option<PathBuf>,
    #[arg(long, default_value_t = 1280)]
    pub(crate) width: u32,
    #[arg(long, default_value_t = 720)]
    pub(crate) height: u32,
    /// Render this many frames, then exit (with --screenshot: save the
    /// last one).
    #[arg(long)]
    pub(crate) frames: Option<u64>,
    /// The PNG --frames saves.
    #[arg(long, value_name = "FILE.png")]
    pub(crate) screenshot: Option<PathBuf>,
    /// Exposure (default: automatic from the first frame).
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) exposure: Option<f32>,
    /// Where each frame's patch light (direct light on the patches and the
    /// gather) runs: gpu, cpu (the CPU run time, H uploaded for the GPU's
    /// shading: for software GL such as llvmpipe), or auto (both timed on
    /// the first frame, the faster kept).
    #[arg(long, default_value = "auto")]
    pub(crate) patch_light: String,
    /// Where there is no display: render the starting view headless to
    /// this PNG instead (GL through EGL, else the CPU) and print its path.
    #[arg(long, value_name = "FILE.png")]
    pub(crate) headless_to: Option<PathBuf>,
    /// Shadow map side in texels.
    #[arg(long, default_value_t = 2048)]
    pub(crate) shadow_resolution: usize,
    /// The most GPU memory the shadow maps may take, in MiB (default: what
    /// the GL grants). A light added beyond it is taken back, with the
    /// sizes on stderr.
    #[arg(long, value_name = "MIB")]
    pub(crate) shadow_budget: Option<f64>,
    /// Keys to press, one after each drawn frame, before the user's:
    /// comma-separated names as winit gives them, each optionally `*COUNT`
    /// ("KeyB,ArrowLeft*3,F5": add a spot, move it left three steps, save).
    /// For demonstrations that repeat exactly, and for tests.
    #[arg(long, value_name = "KEYS")]
    pub(crate) keys: Option<String>,
    /// Sample points per patch for direct light (1..=16).
    #[arg(long, default_value_t = radiosity::runtime::direct::DEFAULT_SAMPLES)]
    pub(crate) samples: usize,
    /// Cull negligible columns of the CPU run time's gathers (--patch-light
    /// cpu): drop the columns of least weight whose bound on H's L1 norm
    /// sums to at most this fraction (0..1; 0: exact, only zero columns
    /// skipped). The default 0.001 added 0.09–0.36 % RMS to H on the
    /// bundled scenes and Sponza, 4–38 % of the codec's own error (`docs/measurements/runtime-cpu.md`).
    #[arg(long, value_name = "EPS", default_value_t = radiosity::runtime::VIEWER_CULL, allow_negative_numbers = true)]
    pub(crate) cull: f64,
    /// Target patch count when baking a scene.
    #[arg(long, default_value_t = 2000)]
    pub(crate) patches: usize,
    #[command(flatten)]
    pub(crate) device: DeviceArgs,
}

#[derive(Args, Clone)]
pub(crate) struct DeviceArgs {
    /// OpenCL device index (see `radiosity devices`); overrides RADIOSITY_CL_DEVICE.
    #[arg(long, value_name = "INDEX")]
    pub(crate) device: Option<usize>,
}

#[derive(Args)]
pub(crate) struct BakeArgs {
    /// The scene: .obj with its .mtl, or glTF 2.0 (.gltf, .glb; metres,
    /// +y up; its doubleSided materials are baked two-sided).
    pub(crate) scene: PathBuf,
    /// Write the bake file (.rad) here (atomically: a temporary file, then
    /// a rename). Without it the bake runs and reports but writes nothing.
    #[arg(short, long, value_name = "OUT.rad")]
    pub(crate) output: Option<PathBuf>,
    /// Voxel edge length in scene units.
    #[arg(long, conflicts_with = "patches", allow_negative_numbers = true)]
    pub(crate) voxel_size: Option<f64>,
    /// Target patch count, of the patches kept (those that see another
    /// surface: a roof under the open sky is removed); the voxel size is
    /// searched for. Default 2000.
    #[arg(long)]
    pub(crate) patches: Option<usize>,
    /// Light bounces folded into the transfer matrix: a number k >= 1, or
    /// `inf` for the converged limit (default: inf).
    #[arg(long, value_parser = parse_bounces)]
    pub(crate) bounces: Option<Bounces>,
    /// Form factors: rays (from the patches' real surfaces, the default) or
    /// contour (contour integrals between patch squares).
    #[arg(long, value_name = "METHOD")]
    pub(crate) form_factors: Option<String>,
    /// Rays per patch of the rays method (16..=1048576, default 16384).
    #[arg(long, value_name = "N")]
    pub(crate) ff_rays_per_patch: Option<u32>,
    /// Rays per patch of the near-field correction (0..=65535; 0: none):
    /// the first reflection from a close neighbour uses the part of it the
    /// patch sees, not its mean (docs/accuracy.md).
    #[arg(long, value_name = "N", default_value_t = radiosity::bake::near_field::DEFAULT_RAYS)]
    pub(crate) near_field_rays: u32,
    /// Near-field links with a measured form factor below this (0..=1) are
    /// not stored; their light still reaches the receivers through each
    /// patch's far weights. Lower keeps more links (larger file).
    #[arg(long, value_name = "F", default_value_t = radiosity::bake::near_field::MIN_FORM_FACTOR, allow_negative_numbers = true)]
    pub(crate) near_field_min_form_factor: f64,
    /// Irradiance probes' spacing: auto (one probe per 8 patches over the
    /// scene's bounds, at least 2 voxels apart), or in voxels (0: no
    /// probes). Moving objects are lit from them (docs/probes.md).
    #[arg(
        long,
        value_name = "auto|VOXELS",
        default_value = "auto",
        allow_negative_numbers = true
    )]
    pub(crate) probe_spacing: String,
    /// Rays per irradiance probe (1..=65536).
    #[arg(long, value_name = "N", default_value_t = radiosity::bake::probes::DEFAULT_RAYS)]
    pub(crate) probe_rays: u32,
    /// Form-factor emitter samples per side, contour method (1..=16, default 4).
    #[arg(long)]
    pub(crate) ff_samples: Option<u32>,
    /// Form-factor visibility rays per patch pair (1..=64, default 4).
    #[arg(long)]
    pub(crate) ff_rays: Option<u32>,
    /// Reordering before compression: none, greedy[:PASSES] (the thesis's,
    /// O(n³)), or hilbert (space-filling curve). Default: greedy:2 up to
    /// 4096 patches, hilbert above.
    #[arg(long, value_name = "METHOD")]
    pub(crate) reorder: Option<String>,
    /// Codec: bc1 (the thesis's: BC1 of log-scaled entries + exact top
    /// fraction), bc4, bc6h, f16 or f32; bc1/bc4 take options, e.g.
    /// `bc1:top=0.02,L=auto,sparse=f16` (sparse values f32, f16 or rgb9e5).
    /// Default: bc1:top=0.04,L=auto,sparse=rgb9e5.
    #[arg(long, value_name = "CODEC", conflicts_with = "max_error")]
    pub(crate) codec: Option<String>,
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
    pub(crate) top_fraction: Option<f64>,
    /// Choose the cheapest codec setting whose relative RMS error of H = T·B0
    /// over the error lights is at most E, preferring BC1/BC4 within twice
    /// its bytes (fast CPU decode); default 0.02 unless --codec or
    /// --top-fraction fixes the setting.
    #[arg(long, value_name = "E", allow_negative_numbers = true)]
    pub(crate) max_error: Option<f64>,
    /// Seeded random lights the compression error is measured over (0: do
    /// not measure; at most 4096).
    #[arg(long, value_name = "N", default_value_t = bake::DEFAULT_ERROR_LIGHTS)]
    pub(crate) error_lights: usize,
    /// Patches on both sides of every surface (recorded in the file; `info`
    /// shows it). Without it, the faces the scene sees from behind (wound
    /// the wrong way, or single-sided panels seen from both sides) get a
    /// back side there only, listed in the bake's summary.
    #[arg(long, conflicts_with = "as_wound")]
    pub(crate) two_sided: bool,
    /// Use every face as wound: no face gets a back side where the scene
    /// sees it from behind (for models one-sided by design, or comparisons
    /// with one-sided renderers).
    #[arg(long)]
    pub(crate) as_wound: bool,
    /// T_inf by `solve` (a blocked LU solve, the default) or `doubling`
    /// (the series, doubled until it converges).
    #[arg(long, value_name = "METHOD")]
    pub(crate) infinite_by: Option<String>,
    /// Write inspection files (patches.csv, patches.png, F.npy, T.npy,
    /// T_decoded.npy, albedo.npy) into this directory.
    #[arg(long, value_name = "DIR")]
    pub(crate) export: Option<PathBuf>,
    /// Run every stage on the CPU reference instead of OpenCL.
    #[arg(long, conflicts_with = "device")]
    pub(crate) cpu_reference: bool,
    #[command(flatten)]
    pub(crate) device: DeviceArgs,
    /// Print the report as JSON on stdout.
    #[arg(long)]
    pub(crate) json: bool,
}

/// `--bounces`: a positive integer or `inf`.
pub(crate) fn parse_bounces(s: &str) -> Result<Bounces, String> {
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

/// The viewer's keys, for `view --help` (the window prints them at start
/// and with H).
fn view_keys() -> String {
    format!("Keys in the window:\n{}", radiosity::viewer::HELP)
}

/// The flags of `bench sweep`.
#[derive(Args)]
pub(crate) struct SweepArgs {
    /// The CI sweep: the Cornell box at 256 and 600 patches, 1 and 3
    /// bounces, BC1 without its sparse part, no reordering.
    #[arg(long)]
    pub(crate) quick: bool,
    /// Scenes: SCENE.obj (camera and lights in SCENE.json beside it) or
    /// SCENE.obj=LIGHTS.json (default: the Cornell box, the interior,
    /// and ../shared/scenes/sponza/sponza.obj when present, under its sun and under the
    /// sun and sky of scenes/external/sponza_noon.json).
    #[arg(long, value_delimiter = ',')]
    pub(crate) scenes: Vec<String>,
    /// Patch counts (default 500,2000,4000).
    #[arg(long, value_delimiter = ',')]
    pub(crate) patches: Vec<usize>,
    /// Bounce counts besides the baseline's ∞ (default 1,2,3).
    #[arg(long, value_delimiter = ',')]
    pub(crate) bounces: Vec<u32>,
    /// Fixed codecs besides the baseline's choice, separated by ';'
    /// (default "bc1:top=0;bc4;bc6h;f16").
    #[arg(long)]
    pub(crate) codecs: Option<String>,
    /// Reorderings besides the default (default none,hilbert).
    #[arg(long, value_delimiter = ',')]
    pub(crate) reorders: Vec<String>,
    #[arg(long, default_value_t = 3)]
    pub(crate) repeat: usize,
    /// Leave out the GL frame.
    #[arg(long)]
    pub(crate) no_gl: bool,
    /// Only the baseline bakes (no bounce, codec or reordering
    /// variants).
    #[arg(long)]
    pub(crate) baseline_only: bool,
    /// The report's directory (the committed reports are docs/sweep
    /// and docs/sweep-mitsuba: name one to update it).
    #[arg(short, long, default_value = "out/sweep")]
    pub(crate) output: PathBuf,
    /// The bound on a baseline point's relative RMS error of H.
    #[arg(long, default_value_t = 0.05, allow_negative_numbers = true)]
    pub(crate) max_error: f64,
    /// The bound on a baseline point's indirect image error against
    /// Mitsuba 3 (noise removed).
    #[arg(long, default_value_t = 0.5, allow_negative_numbers = true)]
    pub(crate) max_image_error: f64,
    /// Leave out the image errors against Mitsuba 3.
    #[arg(long)]
    pub(crate) no_images: bool,
    /// Where the Mitsuba 3 references are, one folder per scene stem;
    /// a missing one is made by scripts/mitsuba-reference (default:
    /// OUTPUT/reference).
    #[arg(long, value_name = "DIR")]
    pub(crate) references: Option<PathBuf>,
    /// Size of the reference images, WxH (default 320x240; quick
    /// 160x120).
    #[arg(long, value_name = "WxH")]
    pub(crate) reference_size: Option<String>,
    /// Samples per pixel of a reference made by the sweep (default
    /// 1024; quick 512).
    #[arg(long)]
    pub(crate) reference_spp: Option<u32>,
    #[command(flatten)]
    pub(crate) device: DeviceArgs,
}
