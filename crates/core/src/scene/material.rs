//! Materials: `Kd`, `Ke` and the mean linear colour of a diffuse texture,
//! resolved and repaired (albedo clamped, missing files counted).

use super::*;

/// Builds the scene materials for the used tobj material ids: `Kd`, `Ke`
/// and the linear texture mean (textures decoded once each, in parallel).
/// Returns the materials and the number of texture files that failed.
pub(super) fn resolve_materials(
    all: &[(tobj::Material, PathBuf)],
    used_ids: &[usize],
    warnings: &mut Vec<String>,
) -> Result<(Vec<Material>, u64), SceneError> {
    // Resolve texture paths relative to their MTL file; decode each once.
    let texture_of = |id: usize| -> Option<PathBuf> {
        let (m, library) = &all[id];
        let spec = m.diffuse_texture.as_deref()?;
        let name = texture_file_name(spec);
        if name.is_empty() {
            return None;
        }
        Some(library.parent().unwrap_or_else(|| Path::new("")).join(name))
    };
    let mut unique: Vec<PathBuf> = used_ids.iter().filter_map(|&id| texture_of(id)).collect();
    unique.sort();
    unique.dedup();
    let decoded: HashMap<PathBuf, Result<[f64; 3], ImageError>> = unique
        .into_par_iter()
        .map(|p| {
            let mean = ImageSource::File(p.clone()).decode().and_then(|image| {
                texture_mean_linear(&image).ok_or_else(|| ImageError::Empty {
                    what: p.display().to_string(),
                })
            });
            (p, mean)
        })
        .collect();
    let mut failures: Vec<&PathBuf> = decoded
        .iter()
        .filter(|(_, r)| r.is_err())
        .map(|(p, _)| p)
        .collect();
    failures.sort();
    for p in &failures {
        let users: Vec<String> = used_ids
            .iter()
            .filter(|&&id| texture_of(id).as_ref() == Some(*p))
            .map(|&id| format!("`{}`", all[id].0.name))
            .collect();
        if let Some(Err(e)) = decoded.get(*p) {
            warnings.push(format!(
                "texture {} (map_Kd of material {}) could not be loaded ({e}); using Kd alone",
                p.display(),
                users.join(", ")
            ));
        }
    }

    let mut materials = Vec::with_capacity(used_ids.len() + 1);
    for &id in used_ids {
        let (m, library) = &all[id];
        let texture = texture_of(id);
        let mean = texture
            .as_ref()
            .and_then(|p| decoded.get(p))
            .and_then(|r| r.as_ref().ok().copied());
        let kd = match m.diffuse {
            Some(kd) => kd,
            None if texture.is_some() => [1.0; 3],
            None => {
                warnings.push(format!(
                    "material `{}` in {} has neither Kd nor map_Kd; using the default albedo \
                     {DEFAULT_ALBEDO}",
                    m.name,
                    library.display()
                ));
                [DEFAULT_ALBEDO; 3]
            }
        };
        let emission = m.emissive.unwrap_or([0.0; 3]);
        for (key, value) in [("Kd", kd), ("Ke", emission)] {
            if value.iter().any(|c| !c.is_finite() || *c < 0.0) {
                return Err(SceneError::Invalid {
                    path: library.clone(),
                    message: format!(
                        "material `{}`: {key} {value:?} has a negative or non-finite component",
                        m.name
                    ),
                });
            }
        }
        let albedo = match mean {
            Some(t) => [0, 1, 2].map(|k| (f64::from(kd[k]) * t[k]) as f32),
            None => kd,
        };
        materials.push(Material {
            name: m.name.clone(),
            albedo,
            emission,
            kd,
            diffuse_texture: texture.filter(|_| mean.is_some()).map(DiffuseTexture::file),
            double_sided: false,
        });
    }
    Ok((materials, failures.len() as u64))
}

/// The file name in a `map_Kd` value: options such as `-bm 0.5` or
/// `-s 1 1 1` precede it (then the last word is taken, so such names must
/// not contain spaces), and Windows separators become `/`.
pub(super) fn texture_file_name(spec: &str) -> String {
    let spec = spec.trim();
    let name = if spec.starts_with('-') {
        spec.split_whitespace().last().unwrap_or("")
    } else {
        spec
    };
    name.replace('\\', "/")
}

/// The mean of a decoded texture's RGB in linear space: each sample is
/// converted from sRGB with the exact EOTF, then averaged. Alpha is
/// ignored; grey images count as equal R, G and B. `None` for an image
/// without pixels.
pub(super) fn texture_mean_linear(image: &image::DynamicImage) -> Option<[f64; 3]> {
    let pixels = u64::from(image.width()) * u64::from(image.height());
    if pixels == 0 {
        return None;
    }
    use image::DynamicImage as D;
    let mean = match image {
        D::ImageRgb8(b) => mean_u8(b.as_raw(), 3, 3),
        D::ImageRgba8(b) => mean_u8(b.as_raw(), 4, 3),
        D::ImageLuma8(b) => mean_u8(b.as_raw(), 1, 1),
        D::ImageLumaA8(b) => mean_u8(b.as_raw(), 2, 1),
        other => {
            // 16-bit and float images: through 16-bit samples.
            let rgb = other.to_rgb16();
            let mut sum = [0.0f64; 3];
            for px in rgb.as_raw().chunks_exact(3) {
                for k in 0..3 {
                    sum[k] += srgb_to_linear(f64::from(px[k]) / 65535.0);
                }
            }
            sum.map(|s| s / pixels as f64)
        }
    };
    Some(mean)
}

/// Linear mean of 8-bit sRGB samples with `stride` bytes per pixel, of
/// which the first `colour` (3, or 1 for grey) are used. A histogram per
/// channel keeps the sum exact and the conversion to 256 evaluations.
pub(super) fn mean_u8(samples: &[u8], stride: usize, colour: usize) -> [f64; 3] {
    let mut histogram = vec![[0u64; 256]; colour];
    let mut pixels = 0u64;
    for px in samples.chunks_exact(stride) {
        for (k, h) in histogram.iter_mut().enumerate() {
            h[px[k] as usize] += 1;
        }
        pixels += 1;
    }
    let lut: Vec<f64> = (0..256).map(|v| srgb_to_linear(v as f64 / 255.0)).collect();
    let means: Vec<f64> = histogram
        .iter()
        .map(|h| {
            let sum: f64 = h.iter().zip(&lut).map(|(&n, &l)| n as f64 * l).sum();
            sum / pixels.max(1) as f64
        })
        .collect();
    if colour == 1 {
        [means[0]; 3]
    } else {
        [means[0], means[1], means[2]]
    }
}
