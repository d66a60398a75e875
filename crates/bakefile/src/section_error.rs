//! What is wrong inside one section of a bake file, as its parser or its
//! checks find it ([`crate::surface::SurfaceMap::from_bytes`],
//! [`crate::near_field::NearField::from_bytes`], their `check`s, the column
//! scales). The container wraps it with the file and the section's tag
//! ([`crate::BakeFileError::Invalid`]); a caller can tell a cut-short file
//! (copy it again) and a newer writer's layout (upgrade) from a corrupt or
//! wrong value.

/// A fault inside one section.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SectionError {
    /// The bytes end before the layout does.
    #[error("{what}: {need} bytes needed at byte {at}, {left} left")]
    Truncated {
        what: &'static str,
        need: u64,
        at: u64,
        left: u64,
    },
    /// The section's length is not the one its counts imply.
    #[error("{found} bytes, expected {expected} ({layout})")]
    Length {
        found: u64,
        expected: u64,
        layout: String,
    },
    /// A layout this build does not read (a newer writer's).
    #[error("{0}")]
    Unsupported(String),
    /// A count whose byte length overflows.
    #[error("{0} count overflows")]
    Overflow(&'static str),
    /// A value out of its range, or inconsistent with another field (the
    /// message names the field, the index and the value).
    #[error("{0}")]
    Invalid(String),
}

impl From<String> for SectionError {
    /// A message naming a wrong value ([`SectionError::Invalid`]).
    fn from(detail: String) -> SectionError {
        SectionError::Invalid(detail)
    }
}

impl From<&str> for SectionError {
    /// As `From<String>`.
    fn from(detail: &str) -> SectionError {
        SectionError::Invalid(detail.to_string())
    }
}
