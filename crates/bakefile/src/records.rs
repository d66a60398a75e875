//! The typed JSON records of a bake file: `OPTS`, the options that shaped
//! the bake ([`OptionsRecord`]), and `INFO`, the bake's report
//! ([`BakeInfo`]). Each is its own versioned schema, defined here with
//! plain types, not a serialisation of the command line or of a stage's
//! configuration: the device a bake ran on, the output path and other
//! options that do not change the result are not recorded.

use serde::{Deserialize, Serialize};

/// Version of the `OPTS` record this build writes and reads.
pub const OPTIONS_RECORD_VERSION: u32 = 1;

/// Version of the `INFO` record this build writes and reads.
pub const INFO_RECORD_VERSION: u32 = 1;

/// Light bounces folded into the matrix, as the records store them: a
/// count, or `"inf"` for the converged limit.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum BouncesRecord {
    K(u32),
    Infinite(InfTag),
}

/// The string `"inf"`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum InfTag {
    #[serde(rename = "inf")]
    Inf,
}

impl BouncesRecord {
    pub const INFINITE: BouncesRecord = BouncesRecord::Infinite(InfTag::Inf);

    /// `Some(k)`, or `None` for the converged limit.
    pub fn count(self) -> Option<u32> {
        match self {
            BouncesRecord::K(k) => Some(k),
            BouncesRecord::Infinite(_) => None,
        }
    }
}

impl std::fmt::Display for BouncesRecord {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            BouncesRecord::K(k) => write!(f, "{k}"),
            BouncesRecord::Infinite(_) => f.write_str("inf"),
        }
    }
}

/// `OPTS`: the options that determine a bake's content, as resolved by the
/// bake (the voxel size actually used, the codec actually chosen).
/// The form-factor method of files that do not name one.
fn contour() -> String {
    "contour".into()
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OptionsRecord {
    /// [`OPTIONS_RECORD_VERSION`].
    pub record_version: u32,
    /// The patch count asked for, when the voxel size was searched for.
    pub target_patches: Option<u64>,
    /// The voxel edge length used (scene units).
    pub voxel_size: f64,
    /// The form-factor method (`rays` or `contour`) and the rays per patch
    /// of the rays method. Files written before the rays method existed
    /// have neither: they were baked with `contour` (and 0 rays).
    #[serde(default = "contour")]
    pub ff_method: String,
    #[serde(default)]
    pub ff_rays_per_patch: u32,
    /// Form-factor emitter samples per side, visibility rays per pair, and
    /// the quadrature's target relative error (contour method).
    pub ff_samples: u32,
    pub ff_rays: u32,
    pub ff_quadrature_tol: f64,
    pub bounces: BouncesRecord,
    /// The reordering's name (e.g. `greedy:2`, `hilbert`).
    pub reorder: String,
    /// The codec setting's name (readable back by `CodecKind::parse`).
    pub codec: String,
    /// How the codec was chosen: `fixed`, or `max-error E`.
    pub codec_choice: String,
    /// The seeded random lights the compression error was measured over.
    pub error_lights: u64,
    pub error_lights_seed: u64,
    /// Patches on both sides of every surface: the run time rebuilds the
    /// baked scene with `Scene::with_back_sides`. Absent in older files
    /// (false).
    #[serde(default)]
    pub two_sided: bool,
    /// The faces the winding check gave a back side (triangle indices of
    /// the scene as loaded, ascending): the run time rebuilds the baked
    /// scene with `Scene::with_back_sides_of`. Absent when empty (and in
    /// older files).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub twinned: Vec<u32>,
}

/// `INFO`: what the bake found and measured, for `info` and for users.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BakeInfo {
    /// [`INFO_RECORD_VERSION`].
    pub record_version: u32,
    /// The program that wrote the file.
    pub generator: String,
    /// The scene file, relative to the bake file's directory when it can be
    /// (so that a bake and its scene can be moved together), else absolute.
    pub scene: String,
    pub triangles: u64,
    pub vertices: u64,
    /// Patches in the matrix (those that see something).
    pub patches: u64,
    pub grey: bool,
    pub spectral_bound: f64,
    /// Relative RMS error of `H = T̃ · B0` against the exact matrix over
    /// the error lights, when measured.
    pub h_error: Option<f64>,
    pub mesh_map_fallbacks: u64,
    pub mesh_map_unmapped: u64,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn options_written_before_the_rays_method_read_as_contour() {
        // The options record of a file baked before `ff_method` existed.
        let old = r#"{"record_version":1,"target_patches":2000,"voxel_size":1.5,
            "ff_samples":4,"ff_rays":4,"ff_quadrature_tol":0.001,"bounces":"inf",
            "reorder":"greedy:2","codec":"bc1-log(top=0.04,L=auto,rgb9e5)",
            "codec_choice":"fixed","error_lights":64,"error_lights_seed":1}"#;
        let r: OptionsRecord = serde_json::from_str(old).expect("an old record reads");
        assert_eq!(r.ff_method, "contour");
        assert_eq!(r.ff_rays_per_patch, 0);
    }
}
