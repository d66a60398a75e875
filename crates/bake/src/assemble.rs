//! Bake step 8, the file's contents: the options record (what was asked
//! and chosen), the info record (what was found and measured) and every
//! section, assembled from what the stages handed on. Writing it is the
//! container's (`radiosity_bakefile::write`).

use crate::config::{BakeConfig, ERROR_LIGHTS_SEED};
use crate::mesh_map::MeshMap;
use crate::report::CodecSummary;
use crate::transfer::{Bounces, Transfer};
use crate::voxelize::Resolution;
use radiosity_bakefile::baked::stored_scene_path;
use radiosity_bakefile::codec::Encoded;
use radiosity_bakefile::near_field::NearField;
use radiosity_bakefile::records::{
    BakeInfo, BouncesRecord, OptionsRecord, INFO_RECORD_VERSION, OPTIONS_RECORD_VERSION,
};
use radiosity_bakefile::sky::SkyVisibility;
use radiosity_bakefile::surface::{PatchSamples, SurfaceMap};
use radiosity_bakefile::{BakeFile, PatchRecord, SceneHash};
use radiosity_core::patch::Patch;
use radiosity_core::permutation::Permutation;
use radiosity_core::scene::Scene;

/// What the stages hand to the file.
pub struct Parts<'a> {
    pub config: &'a BakeConfig,
    /// The scene baked (with its back sides) and the hash of the scene as
    /// loaded.
    pub scene: &'a Scene,
    pub scene_hash: SceneHash,
    pub voxel_size: f64,
    /// The reordering's name.
    pub reorder: String,
    pub encoded: &'a Encoded,
    pub summary: &'a CodecSummary,
    pub error_lights: u64,
    /// The triangles given a back side.
    pub twinned: &'a [u32],
    pub transfer: &'a Transfer,
    pub mesh_map: &'a MeshMap,
    /// The patches in matrix order (before reordering) and the reordering.
    pub patches: &'a [Patch],
    pub permutation: &'a Permutation,
    pub surface_map: SurfaceMap,
    pub samples: PatchSamples,
    pub near_field: NearField,
    /// The sky visibility per patch in matrix order, and the rays per
    /// patch it came from (empty: none).
    pub sky: (&'a [Vec<(u8, f32)>], u32),
    /// The irradiance probes, patches in matrix order (none: no section).
    pub probes: radiosity_bakefile::probes::Probes,
}

/// The bake file of `p`.
pub fn bake_file(p: Parts) -> BakeFile {
    let options = OptionsRecord {
        record_version: OPTIONS_RECORD_VERSION,
        target_patches: match p.config.resolution {
            Resolution::Patches(p) => Some(p as u64),
            Resolution::VoxelSize(_) => None,
        },
        voxel_size: p.voxel_size,
        ff_method: p.config.form_factor.method.name().into(),
        ff_rays_per_patch: p.config.form_factor.rays_per_patch,
        ff_samples: p.config.form_factor.samples,
        ff_rays: p.config.form_factor.rays,
        ff_quadrature_tol: p.config.form_factor.quadrature_tol,
        bounces: match p.config.transfer.bounces {
            Bounces::K(k) => BouncesRecord::K(k),
            Bounces::Infinite => BouncesRecord::INFINITE,
        },
        reorder: p.reorder,
        codec: p.encoded.kind.name(),
        codec_choice: p.summary.chosen_by.clone(),
        error_lights: p.error_lights,
        error_lights_seed: ERROR_LIGHTS_SEED,
        two_sided: p.config.two_sided,
        twinned: p.twinned.to_vec(),
    };
    let scene_stored = match &p.config.output {
        Some(out) => stored_scene_path(out, &p.config.scene),
        None => p.config.scene.display().to_string(),
    };
    let info = BakeInfo {
        record_version: INFO_RECORD_VERSION,
        generator: format!("radiosity {}", env!("CARGO_PKG_VERSION")),
        scene: scene_stored,
        triangles: p.scene.triangles.len() as u64,
        vertices: p.scene.positions.len() as u64,
        patches: p.patches.len() as u64,
        grey: p.transfer.grey,
        spectral_bound: p.transfer.stats.spectral_bound,
        h_error: p.summary.h_error,
        mesh_map_fallbacks: p.mesh_map.stats.fallbacks,
        mesh_map_unmapped: p.mesh_map.stats.unmapped,
    };
    BakeFile {
        options_json: serde_json::to_string(&options).expect("options serialize"),
        scene_hash: p.scene_hash,
        patches: p.patches.iter().map(PatchRecord::from).collect(),
        permutation: p.permutation.order.clone(),
        codec: p.encoded.to_blob(),
        mesh_map: p.mesh_map.entries.clone(),
        surface_map: p.surface_map,
        samples: p.samples,
        near_field: p.near_field,
        sky: if p.sky.0.is_empty() {
            SkyVisibility::none()
        } else {
            SkyVisibility::from_lists(p.sky.1, p.sky.0)
        },
        probes: p.probes,
        info_json: serde_json::to_string(&info).expect("info serializes"),
    }
}
