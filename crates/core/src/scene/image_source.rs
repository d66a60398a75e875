//! Where a material's diffuse texture comes from, and how it is sampled at
//! its edges: an image file beside an OBJ's MTL (`map_Kd`), or an image a
//! glTF file holds (a buffer view of a `.glb`, a data URI) or names (a
//! file), with the glTF sampler's wrap modes. The run time, the GL renderer
//! and the Mitsuba export decode a texture through [`DiffuseTexture::decode`]
//! whatever its source, and the bake file's scene hash hashes its bytes.

use crate::error::ImageError;
use serde::Serialize;
use std::path::PathBuf;
use std::sync::Arc;

/// The bytes of an image: a file, or bytes inside the scene file.
#[derive(Clone, Debug, Serialize)]
pub enum ImageSource {
    /// An image file (resolved: relative to the MTL or glTF file).
    File(PathBuf),
    /// An encoded image (PNG or JPEG) inside the scene file; `label` says
    /// where (`"image 3 (bufferView 7)"`).
    Embedded {
        label: String,
        #[serde(skip)]
        bytes: Arc<[u8]>,
    },
}

/// What a texture coordinate outside `[0, 1]` samples, per axis (glTF's
/// sampler `wrapS`/`wrapT`; OBJ textures repeat).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum Wrap {
    Repeat,
    MirroredRepeat,
    ClampToEdge,
}

impl Wrap {
    /// The texel index for the (possibly out of range) index `i` of an
    /// axis of `n` texels.
    pub fn texel(self, i: i64, n: usize) -> usize {
        let n = n as i64;
        match self {
            Wrap::Repeat => i.rem_euclid(n) as usize,
            Wrap::ClampToEdge => i.clamp(0, n - 1) as usize,
            Wrap::MirroredRepeat => {
                let m = i.rem_euclid(2 * n);
                (if m < n { m } else { 2 * n - 1 - m }) as usize
            }
        }
    }

    /// The OpenGL wrap mode.
    pub fn gl(self) -> u32 {
        // The GL enum values (glcorearb.h), so the core needs no GL crate.
        match self {
            Wrap::Repeat => 0x2901,
            Wrap::MirroredRepeat => 0x8370,
            Wrap::ClampToEdge => 0x812F,
        }
    }
}

/// A material's diffuse (base colour) texture: sRGB-encoded, sampled at
/// the scene's texture coordinates (OBJ convention: `v` up), wrapped per
/// axis (`[s, t]`).
#[derive(Clone, Debug, Serialize)]
pub struct DiffuseTexture {
    pub image: ImageSource,
    pub wrap: [Wrap; 2],
}

impl DiffuseTexture {
    /// A texture file that repeats (OBJ's `map_Kd`).
    pub fn file(path: PathBuf) -> DiffuseTexture {
        DiffuseTexture {
            image: ImageSource::File(path),
            wrap: [Wrap::Repeat; 2],
        }
    }

    /// The file, when the texture is one.
    pub fn path(&self) -> Option<&std::path::Path> {
        match &self.image {
            ImageSource::File(p) => Some(p),
            ImageSource::Embedded { .. } => None,
        }
    }

    /// Decodes the image.
    pub fn decode(&self) -> Result<image::DynamicImage, ImageError> {
        self.image.decode()
    }

    /// The file's path or the embedded image's label, for messages.
    pub fn describe(&self) -> String {
        self.image.describe()
    }
}

impl ImageSource {
    /// Decodes the image (format from its bytes).
    pub fn decode(&self) -> Result<image::DynamicImage, ImageError> {
        fn read(p: &std::path::Path) -> impl Fn(std::io::Error) -> ImageError + '_ {
            move |source| ImageError::Read {
                path: p.to_path_buf(),
                source,
            }
        }
        let decode = |source| ImageError::Decode {
            what: self.describe(),
            source,
        };
        match self {
            ImageSource::File(p) => image::ImageReader::open(p)
                .map_err(read(p))?
                .with_guessed_format()
                .map_err(read(p))?
                .decode()
                .map_err(decode),
            ImageSource::Embedded { bytes, .. } => image::load_from_memory(bytes).map_err(decode),
        }
    }

    /// The file's path or the embedded image's label.
    pub fn describe(&self) -> String {
        match self {
            ImageSource::File(p) => p.display().to_string(),
            ImageSource::Embedded { label, .. } => label.clone(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrap_modes_index_texels_as_gl_does() {
        let n = 4;
        let idx = |w: Wrap| (-5..9).map(|i| w.texel(i, n)).collect::<Vec<_>>();
        assert_eq!(
            idx(Wrap::Repeat),
            [3, 0, 1, 2, 3, 0, 1, 2, 3, 0, 1, 2, 3, 0]
        );
        assert_eq!(
            idx(Wrap::ClampToEdge),
            [0, 0, 0, 0, 0, 0, 1, 2, 3, 3, 3, 3, 3, 3]
        );
        // Mirrored: ... 3 2 1 0 | 0 1 2 3 | 3 2 1 0 | 0 ...
        assert_eq!(
            idx(Wrap::MirroredRepeat),
            [3, 3, 2, 1, 0, 0, 1, 2, 3, 3, 2, 1, 0, 0]
        );
    }
}
