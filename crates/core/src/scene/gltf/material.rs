//! A glTF material as the diffuse model reads it (module `gltf`'s doc):
//! albedo from the base colour and metalness, the base colour texture kept
//! with its sampler, emission from the emissive factor, strength and
//! texture, and what the model leaves out said.

use super::accessor::Buffers;
use super::{data_uri, percent_decode};
use crate::scene::material::texture_mean_linear;
use crate::scene::{DiffuseTexture, ImageSource, Material, Wrap};
use std::path::Path;
use std::sync::Arc;

/// Each material's name, made unique (`name (material 3)` for a repeat;
/// `material 3` without one): the camera-and-lights file's emission map
/// and the reports name materials.
pub(super) fn material_names(doc: &gltf::Document) -> Vec<String> {
    let mut seen = std::collections::HashSet::new();
    doc.materials()
        .map(|m| {
            let i = m.index().unwrap_or(0);
            let name = match m.name() {
                Some(n) if !n.is_empty() => n.to_owned(),
                _ => format!("material {i}"),
            };
            if seen.insert(name.clone()) {
                name
            } else {
                let n = format!("{name} (material {i})");
                seen.insert(n.clone());
                n
            }
        })
        .collect()
}

/// A texture's image and wrap modes. The image's JSON is read directly:
/// `gltf` 1.4.1's `Image::source` unwraps a `mimeType` the spec requires
/// with a buffer view but its validation does not check (a panic, found by
/// the mutations in `tests/gltf/bad.rs`).
fn texture_of(
    doc: &gltf::Document,
    tex: &gltf::Texture,
    dir: &Path,
    buffers: &Buffers,
) -> Result<DiffuseTexture, String> {
    let i = doc.as_json().textures[tex.index()].source.value();
    let doc_image = doc
        .as_json()
        .images
        .get(i)
        .ok_or_else(|| format!("image {i} does not exist"))?;
    let image = match (&doc_image.buffer_view, &doc_image.uri) {
        (Some(v), _) => {
            let v = v.value();
            let view = doc
                .views()
                .nth(v)
                .ok_or_else(|| format!("image {i}: bufferView {v} does not exist"))?;
            let b = buffers
                .0
                .get(view.buffer().index())
                .ok_or_else(|| format!("image {i}: bufferView {v} names a missing buffer"))?;
            let end = view.offset() as u64 + view.length() as u64;
            if end > b.len() as u64 {
                return Err(format!(
                    "image {i}: bufferView {v} reaches byte {end} of a buffer of {}",
                    b.len()
                ));
            }
            ImageSource::Embedded {
                label: format!("image {i} (bufferView {v})"),
                bytes: Arc::from(&b[view.offset()..end as usize]),
            }
        }
        (None, Some(uri)) => match data_uri(uri) {
            Some(bytes) => ImageSource::Embedded {
                label: format!("image {i} (data URI)"),
                bytes: Arc::from(bytes.map_err(|e| format!("image {i}: {e}"))?),
            },
            None => ImageSource::File(dir.join(percent_decode(uri))),
        },
        (None, None) => return Err(format!("image {i} has neither a uri nor a bufferView")),
    };
    let s = tex.sampler();
    let wrap = |w: gltf::texture::WrappingMode| match w {
        gltf::texture::WrappingMode::Repeat => Wrap::Repeat,
        gltf::texture::WrappingMode::MirroredRepeat => Wrap::MirroredRepeat,
        gltf::texture::WrappingMode::ClampToEdge => Wrap::ClampToEdge,
    };
    Ok(DiffuseTexture {
        image,
        wrap: [wrap(s.wrap_s()), wrap(s.wrap_t())],
    })
}

/// The diffuse material (module doc) with what the model leaves out.
pub(super) fn resolve_material(
    doc: &gltf::Document,
    m: &gltf::Material,
    name: &str,
    dir: &Path,
    buffers: &Buffers,
) -> Result<(Material, Vec<String>), String> {
    let mut notes = Vec::new();
    let pbr = m.pbr_metallic_roughness();
    let [r, g, b, _] = pbr.base_color_factor();
    for (key, v) in [
        ("baseColorFactor", [r, g, b]),
        ("emissiveFactor", m.emissive_factor()),
    ] {
        if v.iter().any(|c| !c.is_finite() || *c < 0.0) {
            return Err(format!(
                "{key} {v:?} has a negative or non-finite component"
            ));
        }
    }
    // Metalness: the factor times the texture's mean blue (linear data).
    let mut metallic = f64::from(pbr.metallic_factor());
    if let Some(info) = pbr.metallic_roughness_texture() {
        let t = texture_of(doc, &info.texture(), dir, buffers)?;
        let img = t
            .decode()
            .map_err(|e| format!("metallicRoughnessTexture: {e}"))?;
        let rgb = img.to_rgb8();
        let px = rgb.pixels().len().max(1) as f64;
        let blue: f64 = rgb.pixels().map(|p| f64::from(p[2])).sum::<f64>() / 255.0;
        metallic *= blue / px;
    }
    if !metallic.is_finite() || !(0.0..=1.0).contains(&metallic) {
        return Err(format!("metallic {metallic} lies outside [0, 1]"));
    }
    if metallic > 0.0 {
        notes.push(format!(
            "shows metal as diffuse albedo × (1 − metallic) = × {:.3}",
            1.0 - metallic
        ));
    }
    let kd = [r, g, b].map(|c| (f64::from(c) * (1.0 - metallic)) as f32);
    let texture = match pbr.base_color_texture() {
        Some(info) => {
            let t = texture_of(doc, &info.texture(), dir, buffers)?;
            let img = t.decode().map_err(|e| format!("baseColorTexture: {e}"))?;
            Some((
                texture_mean_linear(&img)
                    .ok_or_else(|| format!("baseColorTexture {} has no pixels", t.describe()))?,
                t,
            ))
        }
        None => None,
    };
    let albedo = match &texture {
        Some((mean, _)) => [0, 1, 2].map(|k| (f64::from(kd[k]) * mean[k]) as f32),
        None => kd,
    };
    let strength = f64::from(m.emissive_strength().unwrap_or(1.0));
    if !strength.is_finite() || strength < 0.0 {
        return Err(format!(
            "emissive_strength {strength} is negative or not finite"
        ));
    }
    let mut radiance = m.emissive_factor().map(|c| f64::from(c) * strength);
    if let Some(info) = m.emissive_texture() {
        let t = texture_of(doc, &info.texture(), dir, buffers)?;
        let img = t.decode().map_err(|e| format!("emissiveTexture: {e}"))?;
        let mean = texture_mean_linear(&img)
            .ok_or_else(|| format!("emissiveTexture {} has no pixels", t.describe()))?;
        for k in 0..3 {
            radiance[k] *= mean[k];
        }
    }
    let emission = radiance.map(|l| (std::f64::consts::PI * l) as f32);
    for ext in ["KHR_materials_pbrSpecularGlossiness", "KHR_materials_unlit"] {
        if m.extensions().is_some_and(|e| e.contains_key(ext)) {
            notes.push(format!(
                "does not read {ext}: the metallic-roughness values (or their defaults) are used"
            ));
        }
    }
    if m.normal_texture().is_some() {
        notes.push("ignores the normal map".to_owned());
    }
    if m.occlusion_texture().is_some() {
        notes.push("ignores the occlusion map (the bake computes occlusion)".to_owned());
    }
    if m.transmission()
        .is_some_and(|t| t.transmission_factor() > 0.0)
    {
        notes.push("shows transmission as opaque".to_owned());
    }
    match m.alpha_mode() {
        gltf::material::AlphaMode::Opaque => {}
        gltf::material::AlphaMode::Mask => notes.push("ignores alpha masking (opaque)".to_owned()),
        gltf::material::AlphaMode::Blend => {
            notes.push("ignores alpha blending (opaque)".to_owned())
        }
    }
    if pbr.roughness_factor() < 0.5 && metallic < 1.0 {
        notes.push(format!(
            "shows a glossy surface (roughness {:.2}) as matte",
            pbr.roughness_factor()
        ));
    }
    Ok((
        Material {
            name: name.to_owned(),
            albedo,
            emission,
            kd,
            diffuse_texture: texture.map(|(_, t)| t),
            double_sided: m.double_sided(),
        },
        notes,
    ))
}
