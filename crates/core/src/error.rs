//! Typed errors of the core: scene loading, the OpenCL layer and the voxel
//! grid. Every variant carries the context a user needs to act on it (the
//! file, the line, the value); the binary wraps them with `anyhow` and
//! prints the whole chain. The bake's errors are in `bake::error`, the bake
//! file's in `bakefile`.

use std::path::PathBuf;

/// Errors raised by the scene loader and the scene description files.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error("cannot read scene file {path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}:{line}: {message}")]
    Parse {
        path: PathBuf,
        line: usize,
        message: String,
    },
    #[error("{path}: {message}")]
    Invalid { path: PathBuf, message: String },
    #[error("{path}: the scene is empty ({detail})")]
    Empty { path: PathBuf, detail: String },
}

/// An image (a texture file, or one a scene file holds) that cannot be
/// read or decoded.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    #[error("cannot read {path}: {source}")]
    Read {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("cannot decode {what}: {source}")]
    Decode {
        /// The file's path or the embedded image's label.
        what: String,
        #[source]
        source: image::ImageError,
    },
    #[error("{what} has no pixels")]
    Empty { what: String },
}

/// Errors from the OpenCL layer.
#[derive(Debug, thiserror::Error)]
pub enum ClError {
    #[error(
        "no OpenCL platform found ({0}); install an OpenCL driver, e.g. `apt-get install \
         pocl-opencl-icd ocl-icd-libopencl1` (scripts/setup does this)"
    )]
    NoPlatform(String),
    #[error("OpenCL device index {index} does not exist: {available} device(s) available (see `radiosity devices`)")]
    NoSuchDevice { index: usize, available: usize },
    #[error(
        "invalid OpenCL device selection {value:?} in {origin}: expected a device index such as 0"
    )]
    BadSelection { value: String, origin: String },
    #[error("OpenCL program {name} failed to build on {device}:\n{log}")]
    Build {
        name: String,
        device: String,
        log: String,
    },
    #[error(
        "buffer {name} needs {bytes} bytes, more than the device {device} allows \
         ({limit_name} = {limit} bytes); use a coarser voxel size or fewer patches"
    )]
    TooLarge {
        name: String,
        bytes: u64,
        device: String,
        limit_name: &'static str,
        limit: u64,
    },
    #[error("OpenCL call failed during {what}: {code}")]
    Api { what: String, code: String },
}

/// A voxel grid that cannot be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GridError {
    #[error("voxel size must be a positive finite number, got {0}")]
    VoxelSize(f64),
    #[error(
        "voxel size {size} is too small for this scene: {voxels} voxels along {axis} (at most \
         {max}); a larger voxel size or fewer patches fits"
    )]
    TooFine {
        size: f64,
        voxels: f64,
        axis: char,
        max: u32,
    },
}

/// A field of the camera-and-lights file (or a sky) whose value is out of
/// range, named by its path in the file (e.g. `lights[1].direction`).
#[derive(Clone, Debug, PartialEq)]
pub struct InvalidField {
    /// The field's path, e.g. `camera.fov_y_deg`.
    pub field: String,
    /// The offending value as written in the file.
    pub value: String,
    /// What is wrong with it.
    pub message: String,
}

impl std::fmt::Display for InvalidField {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} = {}: {}", self.field, self.value, self.message)
    }
}

impl std::error::Error for InvalidField {}
