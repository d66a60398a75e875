//! The validated options of one bake ([`BakeConfig`]): what the binary's
//! flags become, checked before any work starts.

use super::error::BakeError;
use super::form_factor::FormFactorOptions;
use super::reorder::ReorderMethod;
use super::transfer::TransferOptions;
use super::voxelize::Resolution;
use crate::compute::DeviceSelection;
use radiosity_bakefile::codec::CodecKind;
use serde::Serialize;
use std::path::PathBuf;

/// Where the bake's OpenCL stages run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum ComputeChoice {
    /// An OpenCL device (the default).
    OpenCl(DeviceSelection),
    /// The CPU reference implementation of every stage (slow, exact).
    CpuReference,
}

/// How the codec is chosen.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub enum CodecChoice {
    /// This setting.
    Fixed(CodecKind),
    /// The cheapest of `codec::default_candidates` whose relative RMS
    /// error of `H` over the error lights is at most this, preferring a
    /// BC1/BC4 setting within `encode::BLOCK_CODEC_SLACK` of its bytes
    /// (`encode::choose`).
    MaxError(f64),
}

/// The default bound on the compression error: the relative RMS error of
/// `H = T̃ · B0` over the error lights (docs/design.md's 2 %).
pub const DEFAULT_MAX_ERROR: f64 = 0.02;

impl Default for CodecChoice {
    /// The cheapest setting within [`DEFAULT_MAX_ERROR`]: a fixed setting
    /// (the thesis's top 4 % included) misses 2 % on some scenes, so the
    /// bake measures instead of assuming.
    fn default() -> Self {
        CodecChoice::MaxError(DEFAULT_MAX_ERROR)
    }
}

/// Seed of the random lights the compression error is measured over (the
/// same as the compression report's, `docs/compression.md`).
pub const ERROR_LIGHTS_SEED: u64 = 1;

/// Default number of those lights.
pub const DEFAULT_ERROR_LIGHTS: usize = 64;

/// Most error lights a bake takes: each keeps its `B0` (12 bytes a patch)
/// through the compression search, so 4,096 at 16k patches hold 0.8 GB
/// (under a tenth of the bake's own n² matrices); the error's sampling
/// noise is then an eighth of the default's.
pub const MAX_ERROR_LIGHTS: usize = 4096;

/// The validated options of one bake.
#[derive(Clone, Debug, Serialize)]
pub struct BakeConfig {
    pub scene: PathBuf,
    pub resolution: Resolution,
    pub compute: ComputeChoice,
    pub form_factor: FormFactorOptions,
    pub transfer: TransferOptions,
    /// The reordering; `None`: [`ReorderMethod::default_for`] the patch count.
    pub reorder: Option<ReorderMethod>,
    pub codec: CodecChoice,
    /// Seeded random lights the compression error is measured over (0: not
    /// measured; `--max-error` needs at least 1).
    pub error_lights: usize,
    /// Patches on both sides of every surface ([`Scene::with_back_sides`]),
    /// for scenes whose winding is unreliable.
    ///
    /// [`Scene::with_back_sides`]: radiosity_core::scene::Scene::with_back_sides
    pub two_sided: bool,
    /// Use every face as wound: the winding check (`bake::winding`) is
    /// skipped and no face gets a back side of its own (for one-sided
    /// models by design, or comparisons with renderers whose surfaces are
    /// one-sided).
    pub as_wound: bool,
    /// Rays per patch of the near-field correction (0: none;
    /// [`crate::near_field`]).
    pub near_field_rays: u32,
    /// Near-field links below this measured form factor are not stored
    /// (their light still counts, through the far weights;
    /// [`radiosity_bakefile::near_field`]).
    pub near_field_min_form_factor: f64,
    /// The irradiance probes ([`crate::probes`]).
    pub probes: crate::probes::ProbeOptions,
    /// The bake file to write, if any.
    #[serde(skip)]
    pub output: Option<PathBuf>,
    /// Directory for inspection files (`patches.csv`, `patches.png`,
    /// `F.npy`, `T.npy`, `T_decoded.npy`, `albedo.npy`), if asked for.
    #[serde(skip)]
    pub export: Option<PathBuf>,
}

impl BakeConfig {
    /// The default options for `scene` at `resolution`, on the default
    /// OpenCL device, writing nothing.
    pub fn new(scene: PathBuf, resolution: Resolution) -> BakeConfig {
        BakeConfig {
            scene,
            resolution,
            compute: ComputeChoice::OpenCl(DeviceSelection::default()),
            form_factor: FormFactorOptions::default(),
            transfer: TransferOptions::default(),
            reorder: None,
            codec: CodecChoice::default(),
            error_lights: DEFAULT_ERROR_LIGHTS,
            two_sided: false,
            as_wound: false,
            near_field_rays: crate::near_field::DEFAULT_RAYS,
            near_field_min_form_factor: crate::near_field::MIN_FORM_FACTOR,
            probes: crate::probes::ProbeOptions::default(),
            output: None,
            export: None,
        }
    }

    /// The options that change a bake's content, as text (the bake cache's
    /// key; not the device, the output or the exports).
    pub fn cache_key(&self) -> String {
        format!(
            "v{} {:?} {:?} {:?} {:?} {:?} {} near{} far{} probes{}{:?}{}",
            radiosity_bakefile::FORMAT_VERSION,
            self.resolution,
            self.form_factor,
            self.transfer.bounces,
            self.reorder,
            self.codec,
            self.error_lights,
            self.near_field_rays,
            self.near_field_min_form_factor,
            radiosity_bakefile::probes::PROBE_VERSION,
            self.probes,
            if self.two_sided { " two-sided" } else { "" }
        )
    }

    /// Checks option values that do not depend on the scene.
    pub fn validate(&self) -> Result<(), BakeError> {
        if self.two_sided && self.as_wound {
            return Err(BakeError::InvalidOption {
                option: "as_wound",
                value: "true".into(),
                expected: "false with two_sided (back sides everywhere, or as wound: not both)"
                    .into(),
            });
        }
        crate::near_field::check_options(self.near_field_rays, self.near_field_min_form_factor)?;
        self.probes.validate()?;
        if let super::transfer::Bounces::K(k) = self.transfer.bounces {
            let most = super::transfer::MAX_USEFUL_BOUNCES;
            if k == 0 || k > most {
                return Err(BakeError::InvalidOption {
                    option: "bounces",
                    value: k.to_string(),
                    expected: format!(
                        "1..={most}, or infinite (`inf`): beyond {most} bounces the result is the \
                         infinite one's to f32 precision (every albedo is below 0.99), which the \
                         infinite solve computes exactly and faster"
                    ),
                });
            }
        }
        match self.resolution {
            Resolution::VoxelSize(s) if !(s.is_finite() && s > 0.0) => {
                return Err(BakeError::InvalidOption {
                    option: "voxel size",
                    value: s.to_string(),
                    expected: "a positive finite number".into(),
                })
            }
            Resolution::Patches(0) => {
                return Err(BakeError::InvalidOption {
                    option: "patch count",
                    value: "0".into(),
                    expected: "at least 1".into(),
                })
            }
            _ => {}
        }
        if self.error_lights > MAX_ERROR_LIGHTS {
            return Err(BakeError::InvalidOption {
                option: "error lights",
                value: self.error_lights.to_string(),
                expected: format!(
                    "at most {MAX_ERROR_LIGHTS} (each keeps B0 on every patch, 12 bytes a patch, for the whole compression search)"
                ),
            });
        }
        match self.codec {
            CodecChoice::Fixed(kind) => kind.validate()?,
            CodecChoice::MaxError(e) if !(e.is_finite() && e >= 0.0) => {
                return Err(BakeError::InvalidOption {
                    option: "maximum codec error",
                    value: e.to_string(),
                    expected: "a finite number ≥ 0".into(),
                })
            }
            CodecChoice::MaxError(_) if self.error_lights == 0 => {
                return Err(BakeError::InvalidOption {
                    option: "error lights",
                    value: "0".into(),
                    expected: "at least 1 when the codec is chosen by its error".into(),
                })
            }
            CodecChoice::MaxError(_) => {}
        }
        Ok(())
    }
}
