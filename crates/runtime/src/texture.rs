//! Albedo textures for shading (`map_Kd`): decoded once, sRGB to linear,
//! sampled bilinearly with repeat wrapping at the hit's texture
//! coordinates. `ρ(x) = Kd · texture(uv)`, each component clamped to the
//! scene's albedo bound; a material without a texture has its `Kd`
//! albedo. (The GL renderer samples the same texture with mipmaps; its
//! tests allow for the difference under minification.)

use radiosity_core::error::ImageError;
use radiosity_core::scene::{srgb_to_linear, DiffuseTexture, Scene, Wrap, ALBEDO_MAX};

/// A linear RGB texture.
pub struct Texture {
    pub width: usize,
    pub height: usize,
    pub texels: Vec<[f32; 3]>,
    /// Wrap mode per axis (`[s, t]`).
    pub wrap: [Wrap; 2],
}

impl Texture {
    /// Decodes and linearises a material's texture (a file or an image the
    /// scene file holds).
    pub fn load(texture: &DiffuseTexture) -> Result<Texture, ImageError> {
        let img = texture.decode()?.to_rgb8();
        if img.width() == 0 || img.height() == 0 {
            return Err(ImageError::Empty {
                what: texture.describe(),
            });
        }
        let lut: Vec<f32> = (0..256)
            .map(|v| srgb_to_linear(v as f64 / 255.0) as f32)
            .collect();
        Ok(Texture {
            width: img.width() as usize,
            height: img.height() as usize,
            texels: img
                .pixels()
                .map(|p| [lut[p[0] as usize], lut[p[1] as usize], lut[p[2] as usize]])
                .collect(),
            wrap: texture.wrap,
        })
    }

    /// Bilinear sample, wrapped per axis (repeat for OBJ textures), at `uv` (v up, as in OBJ files).
    pub fn sample(&self, uv: [f32; 2]) -> [f32; 3] {
        let (w, h) = (self.width as f32, self.height as f32);
        let x = uv[0] * w - 0.5;
        let y = (1.0 - uv[1]) * h - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let [ws, wt] = self.wrap;
        let at = |i: f32, j: f32| {
            self.texels
                [wt.texel(j as i64, self.height) * self.width + ws.texel(i as i64, self.width)]
        };
        let (a, b, c, d) = (
            at(x0, y0),
            at(x0 + 1.0, y0),
            at(x0, y0 + 1.0),
            at(x0 + 1.0, y0 + 1.0),
        );
        std::array::from_fn(|k| {
            (a[k] * (1.0 - fx) + b[k] * fx) * (1.0 - fy) + (c[k] * (1.0 - fx) + d[k] * fx) * fy
        })
    }
}

/// Every material's albedo texture, loaded (`None`: no texture, or one that
/// could not be read — the loader already counted it as missing).
pub struct Albedo {
    textures: Vec<Option<Texture>>,
}

impl Albedo {
    pub fn new(scene: &Scene) -> Albedo {
        Albedo {
            textures: scene
                .materials
                .iter()
                .map(|m| {
                    m.diffuse_texture
                        .as_ref()
                        .and_then(|t| Texture::load(t).ok())
                })
                .collect(),
        }
    }

    /// `ρ` of material `m` at texture coordinates `uv`.
    pub fn at(&self, scene: &Scene, m: usize, uv: Option<[f32; 2]>) -> [f32; 3] {
        let mat = &scene.materials[m];
        match (&self.textures[m], uv) {
            (Some(t), Some(uv)) => {
                let s = t.sample(uv);
                std::array::from_fn(|c| (mat.kd[c] * s[c]).clamp(0.0, ALBEDO_MAX))
            }
            _ => mat.albedo,
        }
    }
}
