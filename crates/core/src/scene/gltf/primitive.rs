//! One mesh primitive of a glTF file into the scene's geometry: its
//! accessors read with bounds checked, placed by its node's world transform
//! (normals through the inverse transpose, the winding reversed by a
//! mirror), its texture coordinates chosen, transformed and flipped, and
//! its strips and fans cut into triangles (module `gltf`'s doc).

use super::accessor::{read_indices, read_vectors, Buffers};
use super::Skipped;
use crate::scene::build::Raw;
use glam::{DMat3, DMat4, DVec3};
use gltf::mesh::Mode;
use gltf::Semantic;

/// Adds one primitive, placed by `world`, to `raw` (errors name it).
pub(super) fn add_primitive(
    raw: &mut Raw,
    prim: &gltf::Primitive,
    mesh: &gltf::Mesh,
    world: &DMat4,
    buffers: &Buffers,
    skipped: &mut Skipped,
) -> Result<(), String> {
    let what = format!("meshes[{}].primitives[{}]", mesh.index(), prim.index());
    let mode = prim.mode();
    if matches!(
        mode,
        Mode::Points | Mode::Lines | Mode::LineLoop | Mode::LineStrip
    ) {
        skipped.points_lines += 1;
        return Ok(());
    }
    let pos = prim
        .get(&Semantic::Positions)
        .ok_or_else(|| format!("{what} has no POSITION attribute"))?;
    let positions = read_vectors::<3>(&pos, buffers, &format!("{what} POSITION"))?;
    let n = positions.len();
    let base = raw.positions.len();
    if base + n > u32::MAX as usize {
        return Err(format!(
            "more than {} vertices in all; split the scene",
            u32::MAX
        ));
    }
    let same_count = |name: &str, k: usize| -> Result<(), String> {
        if k == n {
            Ok(())
        } else {
            Err(format!("{what} {name} has {k} elements, POSITION has {n}"))
        }
    };
    raw.positions.extend(
        positions
            .iter()
            .map(|&p| world.transform_point3(DVec3::from(p)).as_vec3().to_array()),
    );
    // Normals through the inverse transpose; a singular transform
    // (flattened to a plane) has none to give.
    let linear = DMat3::from_mat4(*world);
    let det = linear.determinant();
    let normal_matrix = (det != 0.0).then(|| linear.inverse().transpose());
    let normals = match (prim.get(&Semantic::Normals), normal_matrix) {
        (Some(a), Some(m)) => {
            let v = read_vectors::<3>(&a, buffers, &format!("{what} NORMAL"))?;
            same_count("NORMAL", v.len())?;
            Some(
                v.into_iter()
                    .map(|v| (m * DVec3::from(v)).normalize_or_zero())
                    .collect::<Vec<_>>(),
            )
        }
        _ => None,
    };
    match normals {
        Some(v) => {
            for nrm in v {
                raw.normals.push(nrm.as_vec3().to_array());
                // A zero or non-finite normal counts as absent.
                raw.has_normal
                    .push(nrm.length_squared() > 0.5 && nrm.is_finite());
            }
        }
        None => {
            raw.normals.resize(base + n, [0.0; 3]);
            raw.has_normal.resize(base + n, false);
        }
    }
    // The texture coordinates the material's base colour texture reads,
    // transformed (KHR_texture_transform) and flipped to `v` up.
    let material = prim.material();
    let info = material.pbr_metallic_roughness().base_color_texture();
    let texcoords = match &info {
        Some(info) => {
            let transform = info.texture_transform();
            let set = transform
                .as_ref()
                .and_then(|t| t.tex_coord())
                .unwrap_or(info.tex_coord());
            match prim.get(&Semantic::TexCoords(set)) {
                Some(a) => {
                    let v = read_vectors::<2>(&a, buffers, &format!("{what} TEXCOORD_{set}"))?;
                    same_count(&format!("TEXCOORD_{set}"), v.len())?;
                    let t = transform.map(|t| UvTransform {
                        offset: t.offset().map(f64::from),
                        rotation: f64::from(t.rotation()),
                        scale: t.scale().map(f64::from),
                    });
                    Some(
                        v.into_iter()
                            .map(|uv| {
                                let [u, v] = t.as_ref().map_or(uv, |t| t.apply(uv));
                                [u as f32, (1.0 - v) as f32]
                            })
                            .collect::<Vec<_>>(),
                    )
                }
                None => {
                    skipped.missing_texcoords += 1;
                    None
                }
            }
        }
        None => None,
    };
    match texcoords {
        Some(v) => {
            skipped.textured += 1;
            raw.texcoords.extend(v);
            raw.has_texcoord.resize(base + n, true);
        }
        None => {
            raw.texcoords.resize(base + n, [0.0; 2]);
            // Without a texture nothing reads the coordinates: none are
            // missing (the scene has texture coordinates when any
            // primitive's texture needs them).
            raw.has_texcoord.resize(base + n, info.is_none());
        }
    }
    let indices: Vec<u32> = match prim.indices() {
        Some(a) => read_indices(&a, buffers, n, &format!("{what} indices"))?,
        None => (0..n as u32).collect(),
    };
    // Triangles by mode (spec 3.7.2.1), a mirror reversing each.
    let flip = det < 0.0;
    let material_id = material.index();
    let mut push = |a: u32, b: u32, c: u32| {
        let t = if flip { [a, c, b] } else { [a, b, c] };
        raw.triangles.push(t.map(|i| (base + i as usize) as u32));
        raw.tri_material.push(material_id);
    };
    match mode {
        Mode::Triangles => {
            if !indices.len().is_multiple_of(3) {
                return Err(format!(
                    "{what}: {} indices do not make whole triangles",
                    indices.len()
                ));
            }
            for t in indices.chunks_exact(3) {
                push(t[0], t[1], t[2]);
            }
        }
        Mode::TriangleStrip => {
            for i in 0..indices.len().saturating_sub(2) {
                let (a, b, c) = (indices[i], indices[i + 1], indices[i + 2]);
                if i % 2 == 0 {
                    push(a, b, c);
                } else {
                    push(b, a, c);
                }
            }
        }
        Mode::TriangleFan => {
            for i in 1..indices.len().saturating_sub(1) {
                push(indices[i], indices[i + 1], indices[0]);
            }
        }
        _ => {}
    }
    Ok(())
}

/// `KHR_texture_transform`: `uv' = T · R · S · uv`, with `R` turning the
/// coordinates counter-clockwise by `rotation` as the extension's GLSL
/// (`u' = cos·u + sin·v`, `v' = −sin·u + cos·v` in `v`-down texture space).
struct UvTransform {
    offset: [f64; 2],
    rotation: f64,
    scale: [f64; 2],
}

impl UvTransform {
    fn apply(&self, [u, v]: [f64; 2]) -> [f64; 2] {
        let (su, sv) = (u * self.scale[0], v * self.scale[1]);
        let (s, c) = self.rotation.sin_cos();
        [
            c * su + s * sv + self.offset[0],
            -s * su + c * sv + self.offset[1],
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn texture_transform_follows_the_extensions_example() {
        // The extension's example: offset [0, 1], rotation π/2, scale 0.5
        // shows the lower left quadrant turned: uv (1, 0) lands at (0, 0.5).
        let t = UvTransform {
            offset: [0.0, 1.0],
            rotation: std::f64::consts::FRAC_PI_2,
            scale: [0.5, 0.5],
        };
        let [u, v] = t.apply([1.0, 0.0]);
        assert!(u.abs() < 1e-12 && (v - 0.5).abs() < 1e-12, "{u} {v}");
        let [u, v] = t.apply([0.0, 0.0]);
        assert!(u.abs() < 1e-12 && (v - 1.0).abs() < 1e-12);
    }
}
