//! What a command writes, checked before it does any work:
//!
//! - **never one of its inputs**: an output that names a file the command
//!   reads — the scene's OBJ, its MTL libraries and their images
//!   ([`radiosity::core::scene::files`]), the camera-and-lights JSON, the
//!   bake — is refused with the flag and the input it would destroy, and
//!   nothing is written. The same file reached through another path, a
//!   symbolic link or a hard link counts (device and inode);
//! - **a folder that takes it**: the nearest existing folder on its path
//!   takes a new file (one is created and removed there) and nothing that
//!   is not a folder stands in the way, so that a read-only or impossible
//!   place fails at once instead of after a bake of minutes; a missing
//!   folder is made when the file is written, so a refused command leaves
//!   none behind;
//! - **the format its name says**: an image's extension chooses PNG or JPEG
//!   and anything else is refused (a `-o x.jpg` once got PNG bytes).
//!
//! Every file is then written to a temporary file renamed into place
//! ([`radiosity::bakefile::container::write_atomic`]), so a failure leaves
//! the old file whole.

use anyhow::{bail, Context as _};
use std::os::unix::fs::MetadataExt;
use std::path::{Path, PathBuf};

/// One file a command reads: its path as given, what it is, and its
/// identity (canonical path; device and inode where it exists).
struct Input {
    path: PathBuf,
    what: String,
    canonical: Option<PathBuf>,
    id: Option<(u64, u64)>,
}

/// The canonical form of `p`: itself resolved where it exists, else its
/// existing folder resolved and its name appended (an output not yet
/// written).
fn canonical(p: &Path) -> Option<PathBuf> {
    if let Ok(c) = p.canonicalize() {
        return Some(c);
    }
    let name = p.file_name()?;
    let dir = match p.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    dir.canonicalize().ok().map(|d| d.join(name))
}

/// The files a command reads ([`Inputs::check`] refuses outputs among them).
#[derive(Default)]
pub(crate) struct Inputs {
    files: Vec<Input>,
}

impl Inputs {
    pub(crate) fn new() -> Inputs {
        Inputs::default()
    }

    /// `path` is read, as `what` ("the scene", "the bake", ...).
    pub(crate) fn file(&mut self, path: &Path, what: &str) -> &mut Inputs {
        let id = std::fs::metadata(path).ok().map(|m| (m.dev(), m.ino()));
        self.files.push(Input {
            path: path.to_path_buf(),
            what: what.to_string(),
            canonical: canonical(path),
            id,
        });
        self
    }

    /// The scene at `obj` is read: the OBJ, its MTL libraries and their
    /// images. A scene that cannot be read adds only itself (loading it
    /// reports why).
    pub(crate) fn scene(&mut self, obj: &Path) -> &mut Inputs {
        match radiosity::core::scene::files::source_files(obj) {
            Ok(files) => {
                for (k, f) in files.iter().enumerate() {
                    let what = match k {
                        0 => "the scene".to_string(),
                        _ if f.extension().is_some_and(|e| e.eq_ignore_ascii_case("mtl")) => {
                            format!("a material library of {}", obj.display())
                        }
                        _ if f.extension().is_some_and(|e| e.eq_ignore_ascii_case("bin")) => {
                            format!("a buffer of {}", obj.display())
                        }
                        _ => format!("a texture of {}", obj.display()),
                    };
                    self.file(f, &what);
                }
            }
            Err(_) => {
                self.file(obj, "the scene");
            }
        }
        self
    }

    /// `out`, written through `flag`, is none of the inputs; else an error
    /// naming both (and nothing has been written).
    pub(crate) fn check(&self, out: &Path, flag: &str) -> anyhow::Result<()> {
        let out_id = std::fs::metadata(out).ok().map(|m| (m.dev(), m.ino()));
        let out_canonical = canonical(out);
        for i in &self.files {
            let same_file = out_id.is_some() && out_id == i.id;
            let same_path = out_canonical.is_some() && out_canonical == i.canonical;
            if same_file || same_path {
                bail!(
                    "{flag} {}: that is {} this command reads ({}); refusing to write over it (nothing was written)",
                    out.display(),
                    i.what,
                    i.path.display()
                );
            }
        }
        Ok(())
    }

    /// Every file `files` (written into a folder through `flag`) is none of
    /// the inputs.
    pub(crate) fn check_all(&self, files: &[PathBuf], flag: &str) -> anyhow::Result<()> {
        files.iter().try_for_each(|f| self.check(f, flag))
    }
}

/// Makes sure `out` can be written before the work that produces it,
/// without creating anything: the folder it goes in may be missing (it is
/// made when the file is written), but the nearest folder that exists
/// must take a new file (one is created and removed there), and nothing
/// that is not a folder may stand in its way. A path that names a folder
/// is refused.
pub(crate) fn writable(out: &Path, flag: &str) -> anyhow::Result<()> {
    if out.is_dir() {
        bail!(
            "{flag} {}: that is a folder, not a file name",
            out.display()
        );
    }
    if out.file_name().is_none() {
        bail!("{flag} {}: names no file", out.display());
    }
    let dir = match out.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    writable_dir(&dir, flag)
}

/// Makes sure files can be written into the folder `dir` (which may be
/// missing) before the work that produces them, creating nothing
/// ([`writable`]).
pub(crate) fn writable_dir(dir: &Path, flag: &str) -> anyhow::Result<()> {
    // The nearest part of the path that exists.
    let mut existing = dir;
    while !existing.exists() {
        match existing.parent() {
            Some(p) if !p.as_os_str().is_empty() => existing = p,
            _ => {
                existing = Path::new(".");
                break;
            }
        }
    }
    if !existing.is_dir() {
        bail!(
            "{flag}: cannot create the folder {}: {} is not a folder",
            dir.display(),
            existing.display()
        );
    }
    let probe = existing.join(format!(".radiosity-write-test.{}", std::process::id()));
    std::fs::File::create(&probe).with_context(|| {
        format!(
            "{flag}: cannot write into {} (to make {})",
            existing.display(),
            dir.display()
        )
    })?;
    let _ = std::fs::remove_file(&probe);
    Ok(())
}

/// Creates the folder `out` goes in, where missing (right before writing).
pub(crate) fn make_parent(out: &Path) -> anyhow::Result<()> {
    match out.parent() {
        Some(d) if !d.as_os_str().is_empty() => std::fs::create_dir_all(d)
            .with_context(|| format!("creating the folder {}", d.display())),
        _ => Ok(()),
    }
}

/// An image file format chosen by the output's extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum ImageFormat {
    Png,
    Jpeg,
}

impl ImageFormat {
    /// The format `out`'s extension names (`.png`, `.jpg`, `.jpeg`, any
    /// case); any other extension, or none, is refused.
    pub(crate) fn of(out: &Path, flag: &str) -> anyhow::Result<ImageFormat> {
        let ext = out
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase());
        match ext.as_deref() {
            Some("png") => Ok(ImageFormat::Png),
            Some("jpg" | "jpeg") => Ok(ImageFormat::Jpeg),
            Some(e) => bail!(
                "{flag} {}: cannot write .{e} images (expected .png, .jpg or .jpeg)",
                out.display()
            ),
            None => bail!(
                "{flag} {}: no extension to choose the image format by (expected .png, .jpg or .jpeg)",
                out.display()
            ),
        }
    }

    pub(crate) fn image_format(self) -> image::ImageFormat {
        match self {
            ImageFormat::Png => image::ImageFormat::Png,
            ImageFormat::Jpeg => image::ImageFormat::Jpeg,
        }
    }
}

/// `--hdr`'s format: `.pfm` only (the linear radiance as written by
/// [`radiosity::runtime::tonemap::write_pfm`]).
pub(crate) fn check_pfm(out: &Path, flag: &str) -> anyhow::Result<()> {
    match out
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
    {
        Some(e) if e == "pfm" => Ok(()),
        _ => bail!(
            "{flag} {}: the linear image is written as PFM: name it .pfm",
            out.display()
        ),
    }
}
