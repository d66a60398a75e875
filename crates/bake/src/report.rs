//! The bake's report: time per stage, what each stage found, the codec's
//! sizes and error, printed at the end of a bake (or as JSON), and the
//! progress bars shown while it runs.

use super::config::ERROR_LIGHTS_SEED;
use super::form_factor::FormFactorStats;
use super::mesh_map::MeshMapStats;
use super::reorder::ReorderStats;
use super::surface_map::SurfaceMapStats;
use super::transfer::TransferStats;
use super::voxelize::VoxelStats;
use radiosity_bakefile::codec::Encoded;
use radiosity_core::patch::Direction;
use radiosity_core::scene::SceneSummary;
use serde::Serialize;
use std::path::PathBuf;

/// Time and outcome of one stage.
#[derive(Clone, Debug, Serialize)]
pub struct StageTime {
    pub stage: &'static str,
    pub seconds: f64,
    /// Where it ran: the OpenCL device's name, or the host's threads
    /// ([`host_threads`]).
    pub device: String,
}

/// The host as a stage's device: "CPU (N threads)".
pub fn host_threads() -> String {
    format!("CPU ({} threads)", rayon::current_num_threads())
}

/// The compressed matrix of a bake: the setting, its sizes and its error.
#[derive(Clone, Debug, Serialize)]
pub struct CodecSummary {
    /// The setting (`CodecKind::name`).
    pub codec: String,
    /// How it was chosen: `"fixed"` or `"max-error E"`.
    pub chosen_by: String,
    /// Bytes of the dense tiles, the sparse part and the tile index.
    pub bytes_dense: u64,
    pub bytes_sparse: u64,
    pub bytes_index: u64,
    /// All bytes per matrix entry (three channels together), and the dense
    /// and sparse parts' shares.
    pub bytes_per_entry: f64,
    pub bytes_per_entry_dense: f64,
    pub bytes_per_entry_sparse: f64,
    /// Uncompressed f32 size of the three channels over the total.
    pub compression_ratio: f64,
    /// Tiles of the dense part that are zero in every channel, not stored.
    pub zero_tile_fraction: f64,
    /// Relative RMS error of `H = T̃ · B0` against `T · B0` over the error
    /// lights (`None` when not measured).
    pub h_error: Option<f64>,
    pub error_lights: usize,
    pub error_lights_seed: u64,
}

impl CodecSummary {
    /// The summary of `e` (error measured elsewhere).
    pub fn of(e: &Encoded, chosen_by: String, h_error: Option<f64>, lights: usize) -> CodecSummary {
        let entries = (e.n * e.n).max(1) as f64;
        CodecSummary {
            codec: e.kind.name(),
            chosen_by,
            bytes_dense: e.bytes_dense() as u64,
            bytes_sparse: e.bytes_sparse() as u64,
            bytes_index: e.bytes_index() as u64,
            bytes_per_entry: e.bytes_per_entry(),
            bytes_per_entry_dense: e.bytes_dense() as f64 / entries,
            bytes_per_entry_sparse: e.bytes_sparse() as f64 / entries,
            compression_ratio: 12.0 * entries / e.bytes_total().max(1) as f64,
            zero_tile_fraction: e.zero_tile_fraction(),
            h_error,
            error_lights: lights,
            error_lights_seed: ERROR_LIGHTS_SEED,
        }
    }
}

impl std::fmt::Display for CodecSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(f, "codec: {} ({})", self.codec, self.chosen_by)?;
        writeln!(
            f,
            "  bytes per matrix entry: {:.4} dense + {:.4} sparse + {:.4} index = {:.4} \
             ({} + {} + {} bytes; {:.1}x smaller than f32)",
            self.bytes_per_entry_dense,
            self.bytes_per_entry_sparse,
            self.bytes_per_entry - self.bytes_per_entry_dense - self.bytes_per_entry_sparse,
            self.bytes_per_entry,
            self.bytes_dense,
            self.bytes_sparse,
            self.bytes_index,
            self.compression_ratio
        )?;
        writeln!(
            f,
            "  zero tiles skipped: {:.1} %",
            100.0 * self.zero_tile_fraction
        )?;
        match self.h_error {
            Some(e) => write!(
                f,
                "  compression error: relative RMS error of H = T̃·B0 {:.3} % over {} seeded \
                 random lights (seed {:#x})",
                100.0 * e,
                self.error_lights,
                self.error_lights_seed
            ),
            None => write!(f, "  compression error: not measured (no error lights)"),
        }
    }
}

/// What a bake did, for the terminal and for `--json`.
#[derive(Clone, Debug, Serialize)]
pub struct BakeReport {
    pub scene: SceneSummary,
    pub device: String,
    pub voxels: VoxelStats,
    pub form_factors: FormFactorStats,
    pub facing: crate::facing::Facing,
    /// Faces given a back side (module `winding`).
    pub winding: crate::winding::Winding,
    pub transfer: TransferStats,
    pub reorder: ReorderStats,
    pub codec: CodecSummary,
    pub mesh_map: MeshMapStats,
    pub surface_map: SurfaceMapStats,
    pub near_field: crate::near_field::NearFieldStats,
    /// The irradiance probes (all zero without).
    pub probes: crate::probes::ProbeStats,
    /// The bake file written, if any.
    pub output: Option<PathBuf>,
    pub stages: Vec<StageTime>,
}

/// A progress bar on stderr for a stage measured in `unit`s (hidden when
/// stderr is not a terminal).
pub fn bar(stage: &str) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new(0);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{prefix:>14} [{bar:40}] {pos}/{len} ({eta} left)")
            .expect("a valid template")
            .progress_chars("=> "),
    );
    bar.set_prefix(stage.to_string());
    bar
}

/// A progress bar for a stage whose work has an upper bound it may stop
/// short of (the codec choice's candidates): the count and the time left
/// are both marked as at most.
pub fn bar_at_most(stage: &str, unit: &str) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new(0);
    bar.set_style(
        indicatif::ProgressStyle::with_template(&format!(
            "{{prefix:>14}} [{{bar:40}}] {{pos}}/{{len}} {unit} at most ({{eta}} left at most)"
        ))
        .expect("a valid template")
        .progress_chars("=> "),
    );
    bar.set_prefix(stage.to_string());
    bar
}

/// A spinner with the elapsed time for a stage that cannot count its work
/// (hidden when stderr is not a terminal).
pub fn spinner(stage: &str) -> indicatif::ProgressBar {
    let sp = indicatif::ProgressBar::new_spinner();
    sp.set_style(
        indicatif::ProgressStyle::with_template("{prefix:>14} {spinner} {elapsed}")
            .expect("a valid template"),
    );
    sp.set_prefix(stage.to_string());
    sp.enable_steady_tick(std::time::Duration::from_millis(200));
    sp
}

impl std::fmt::Display for BakeReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let v = &self.voxels;
        writeln!(f, "device: {}", self.device)?;
        writeln!(f, "{}", self.winding)?;
        writeln!(
            f,
            "voxels: size {:.6} {}, grid {}x{}x{}, {} occupied, {} triangle/voxel pieces ({} candidates, {} slivers of total area {:.3e})",
            v.voxel_size,
            // glTF fixes metres; an OBJ has no unit.
            if self.scene.units == "metres" { "m" } else { "scene units" },
            v.grid_dims[0],
            v.grid_dims[1],
            v.grid_dims[2],
            v.occupied_voxels,
            v.pieces,
            v.candidate_pieces,
            v.sliver_pieces,
            v.sliver_area
        )?;
        let per_dir: Vec<String> = Direction::ALL
            .iter()
            .map(|d| format!("{} {}", d.name(), v.patches_per_direction[*d as usize]))
            .collect();
        writeln!(f, "patches: {} ({})", v.patches, per_dir.join(", "))?;
        writeln!(
            f,
            "{}; {} fragments joined to a neighbour",
            v.spread, v.fragments_joined
        )?;
        writeln!(
            f,
            "area: patches {:.6e} of scene {:.6e} ({:.2} %); {} staircase groups merged, {} pieces cut by a wall, {} split where a surface separates them, {} facing a surface within two voxels (kept); covered: {} pieces dropped, {} partly, area {:.3e} ({}); {} albedo components clamped",
            v.patch_area,
            v.scene_area,
            100.0 * v.patch_area / v.scene_area.max(f64::MIN_POSITIVE),
            v.merged_groups,
            v.cut_pieces,
            v.split_groups,
            v.facing_back_groups,
            v.covered_pieces,
            v.partly_covered_pieces,
            v.covered_area,
            Direction::ALL
                .iter()
                .map(|d| format!("{} {:.3e}", d.name(), v.covered_area_per_direction[*d as usize]))
                .collect::<Vec<_>>()
                .join(", "),
            v.clamped_albedo
        )?;
        if v.search.len() > 1 {
            let tries: Vec<String> = v
                .search
                .iter()
                .map(|(s, n)| format!("{s:.4} -> {n}"))
                .collect();
            writeln!(f, "voxel size search: {}", tries.join(", "))?;
        }
        writeln!(
            f,
            "voxelize detail: pieces {:.3} s (kernels {:.3} s), reduce {:.3} s",
            v.seconds_pieces, v.seconds_kernels, v.seconds_reduce
        )?;
        writeln!(f, "{}", self.form_factors)?;
        let fc = &self.facing;
        writeln!(
            f,
            "facing: {:.1} % of the patch area sees nothing{}",
            100.0 * fc.blind_area_share,
            if fc.probe_rays > 0 {
                format!(
                    "; back-side probe: {:.1} % of {} rays met back faces",
                    100.0 * fc.probe_back_share,
                    fc.probe_rays
                )
            } else {
                String::new()
            }
        )?;
        if fc.reversed_patches > 0 {
            writeln!(
                f,
                "  {} blind patches ({:.1} % of the area) see the fronts of other surfaces \
                 from their back sides",
                fc.reversed_patches,
                100.0 * fc.reversed_area_share
            )?;
        }
        for w in &fc.warnings {
            writeln!(f, "warning: {w}")?;
        }
        writeln!(f, "{}", self.transfer)?;
        let r = &self.reorder;
        writeln!(
            f,
            "reorder: {}, {:.3} s; mean distance between consecutive rows {:.4e} -> {:.4e}",
            r.method, r.seconds, r.adjacent_distance_before, r.adjacent_distance_after
        )?;
        writeln!(f, "{}", self.codec)?;
        let m = &self.mesh_map;
        writeln!(
            f,
            "mesh map: {} vertices, {:.2} patches each on average; {} from a widened search, \
             {} fallbacks ({} blocked by walls), {} unmapped; {:.3} s",
            m.vertices,
            m.mean_patches,
            m.widened,
            m.fallbacks,
            m.fallbacks_blocked,
            m.unmapped,
            m.seconds
        )?;
        let s = &self.surface_map;
        writeln!(
            f,
            "surface map: {} pieces of {} triangles: {} lit by their own patch, {} by a \
             substitute ({:.4} units²), {} by none ({:.4} units²); {:.2} lattice neighbours \
             per patch ({} candidates behind a surface); {} patches sampled at piece \
             centroids; {:.3} s",
            s.pieces,
            s.triangles,
            s.pieces_own,
            s.pieces_substitute,
            s.area_substitute,
            s.pieces_unmapped,
            s.area_unmapped,
            s.mean_neighbours,
            s.neighbours_blocked,
            s.patches_centroid_samples,
            s.seconds
        )?;
        let nf = &self.near_field;
        writeln!(
            f,
            "near field: {} rays per patch, {} links ({:.1} per patch, form factor ≥ {}), {} bytes; {:.3} s",
            nf.rays_per_patch,
            nf.links,
            nf.links_per_patch,
            nf.min_form_factor,
            nf.bytes,
            nf.seconds
        )?;
        writeln!(f)?;
        writeln!(f, "summary")?;
        writeln!(
            f,
            "  n = {} patches, {} bounces, {} reordering, codec {}",
            self.transfer.n, self.transfer.bounces, r.method, self.codec.codec
        )?;
        let total: f64 = self.stages.iter().map(|s| s.seconds).sum();
        write!(f, "  time per stage:")?;
        for s in &self.stages {
            write!(f, " {} {:.2} s;", s.stage, s.seconds)?;
        }
        writeln!(f, " total {total:.2} s")?;
        // Where they ran, grouped: most stages run on the host.
        let mut devices: Vec<(&str, Vec<&str>)> = Vec::new();
        for s in &self.stages {
            match devices.iter_mut().find(|(d, _)| *d == s.device) {
                Some((_, names)) => names.push(s.stage),
                None => devices.push((&s.device, vec![s.stage])),
            }
        }
        let on: Vec<String> = devices
            .iter()
            .map(|(d, names)| format!("{} on {d}", names.join(", ")))
            .collect();
        writeln!(f, "  stages: {}", on.join("; "))?;
        writeln!(
            f,
            "  bytes per matrix entry: dense {:.4}, sparse {:.4}, total {:.4} (all 3 channels, \
             index included)",
            self.codec.bytes_per_entry_dense,
            self.codec.bytes_per_entry_sparse,
            self.codec.bytes_per_entry
        )?;
        writeln!(
            f,
            "  tiles skipped: {:.1} %",
            100.0 * self.codec.zero_tile_fraction
        )?;
        for w in &self.facing.warnings {
            writeln!(f, "  warning: {w}")?;
        }
        match self.codec.h_error {
            Some(e) => writeln!(
                f,
                "  compression error: {:.3} % relative RMS of H over {} random lights",
                100.0 * e,
                self.codec.error_lights
            )?,
            None => writeln!(f, "  compression error: not measured")?,
        }
        match &self.output {
            Some(p) => writeln!(f, "  wrote {}", p.display()),
            None => writeln!(f, "  no bake file written (give -o OUT.rad)"),
        }
    }
}
