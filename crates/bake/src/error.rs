//! The bake's typed errors. Each variant is a cause a caller can act on:
//! an option out of its range (change the option), a request beyond a
//! limit (fewer patches), inputs that do not fit together (a caller's bug),
//! a non-finite or degenerate value (bad input data), an export that cannot
//! be written, or an error of a layer below. Messages name options as the
//! library knows them (`voxel size`), never command-line flags: the binary
//! adds those.

use radiosity_core::error::{ClError, GridError, SceneError};
use std::path::PathBuf;

/// Errors from the bake stages.
#[derive(Debug, thiserror::Error)]
pub enum BakeError {
    /// An option value outside its valid range.
    #[error("invalid {option}: {value} (expected {expected})")]
    InvalidOption {
        option: &'static str,
        value: String,
        expected: String,
    },
    /// A voxel size at which no surface makes a patch: voxels much larger
    /// than the scene, in which every surface lies within the covering gap
    /// of another (or is a sliver). A smaller voxel size (more patches)
    /// bakes.
    #[error(
        "voxelize: no patches at voxel size {voxel_size:.3e}: of {pieces} pieces, {covered} are covered (another surface within the covering gap of {gap} voxels) and {slivers} are slivers; the scene's largest extent is {extent:.3e}, so the voxel size must be well below it"
    )]
    NoPatches {
        voxel_size: f64,
        pieces: u64,
        covered: u64,
        slivers: u64,
        gap: f64,
        extent: f64,
    },
    /// A request beyond a limit of a stage (sizes, index ranges): fewer
    /// patches or a coarser voxel size fits.
    #[error("{stage}: {detail}")]
    TooLarge { stage: &'static str, detail: String },
    /// Inputs of a stage whose sizes or contents do not fit together.
    #[error("{stage}: {detail}")]
    Mismatch { stage: &'static str, detail: String },
    /// A non-finite, negative or degenerate value where the mathematics
    /// needs a valid one.
    #[error("{stage}: {detail}")]
    Numeric { stage: &'static str, detail: String },
    /// Surfaces that see nothing: faces wound away from each other, or a
    /// scene with nothing for light to bounce between (`bake::facing`).
    #[error("facing: {detail}")]
    Facing { detail: String },
    /// An inspection file that cannot be written.
    #[error("cannot write {path}: {detail}")]
    Export { path: PathBuf, detail: String },
    /// A file or directory the bake needs that cannot be made or written
    /// (`what`: "create the output directory", ...).
    #[error("cannot {what} {path}: {source}")]
    Io {
        what: &'static str,
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The scene's camera-and-lights file is invalid (it names the file).
    #[error(transparent)]
    Config(#[from] radiosity_core::scene_config::ConfigError),
    #[error(transparent)]
    Scene(#[from] SceneError),
    #[error(transparent)]
    Cl(#[from] ClError),
    #[error(transparent)]
    Grid(#[from] GridError),
    #[error(transparent)]
    Encode(#[from] crate::encode::EncodeError),
    #[error(transparent)]
    Choose(#[from] crate::encode::measure::ChooseError),
    #[error(transparent)]
    CodecSetting(#[from] radiosity_bakefile::codec::CodecSettingError),
    #[error(transparent)]
    CodecData(#[from] radiosity_bakefile::codec::CodecDataError),
    #[error(transparent)]
    Permutation(#[from] radiosity_core::permutation::PermutationError),
    #[error(transparent)]
    File(#[from] radiosity_bakefile::BakeFileError),
}

impl BakeError {
    /// The option at fault, for [`BakeError::InvalidOption`].
    pub fn option(&self) -> Option<&'static str> {
        match self {
            BakeError::InvalidOption { option, .. } => Some(option),
            _ => None,
        }
    }
}
