//! Mitsuba 3 as the independent reference (docs/design.md section 3, measure 4):
//! [`export()`] writes a scene with its camera, lights and emission scales as
//! a Mitsuba scene, `scripts/mitsuba-reference` renders it (its own Python
//! environment, cached by a hash of the export), and [`mod@reference`] reads
//! the images back and measures the run time's images against them, with
//! the reference's own noise known and removed from the error.
//!
//! Imports `core` (scene, lights) and `runtime` (the albedo textures and
//! the PFM writer, so that the exported `ρ(x)` is the one the run time
//! shades with); nothing imports it but `bench` and the binary.

pub mod export;
pub mod reference;

pub use export::{export, ExportError, ExportOptions, ExportSummary};
pub use reference::{image_error, ImageError, Reference, ReferenceError};
