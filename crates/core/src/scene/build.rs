//! The loaded OBJ's meshes turned into a [`Scene`]: vertices welded into
//! one array, faces triangulated and checked (degenerate, out of range,
//! non-finite), materials resolved, normals filled where the file has none,
//! and every repair counted ([`super::Repairs`]).

use super::material::resolve_materials;
use super::tap::{coordinate_problem, locate_bad_vertex};
use super::triangulate;
use super::{
    Material, ObjState, Repairs, Scene, ALBEDO_MAX, DEFAULT_ALBEDO, DEFAULT_MATERIAL_NAME,
    DEGENERATE_AREA_RATIO,
};
use crate::error::SceneError;
use crate::math::{add, cross, dot, norm, sub};
use std::path::Path;

/// Merges tobj's models, validates and repairs them and resolves materials.
pub(super) fn build_scene(
    path: &Path,
    models: Vec<tobj::Model>,
    mut st: ObjState,
) -> Result<Scene, SceneError> {
    let invalid = |message: String| SceneError::Invalid {
        path: path.to_path_buf(),
        message,
    };

    // Merge all models into one vertex array, remembering which vertices
    // carry a normal / texcoord from the file.
    let mut positions: Vec<[f32; 3]> = Vec::new();
    let mut normals: Vec<[f32; 3]> = Vec::new();
    let mut has_normal: Vec<bool> = Vec::new();
    let mut texcoords: Vec<[f32; 2]> = Vec::new();
    let mut has_texcoord: Vec<bool> = Vec::new();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    let mut tri_material: Vec<Option<usize>> = Vec::new();
    let mut misaligned_meshes = 0usize;
    // Polygon faces cut by ear clipping, and those it could not cut.
    let (mut nonconvex, mut untriangulated) = (0u64, 0u64);
    for model in &models {
        let mesh = &model.mesh;
        let n = mesh.positions.len() / 3;
        let base = positions.len();
        if base + n > u32::MAX as usize {
            return Err(invalid(format!(
                "more than {} vertices after triangulation; split the scene",
                u32::MAX
            )));
        }
        positions.extend(mesh.positions.chunks_exact(3).map(|p| [p[0], p[1], p[2]]));
        let mesh_normals = mesh.normals.len() == 3 * n;
        let mesh_texcoords = mesh.texcoords.len() == 2 * n;
        if (!mesh.normals.is_empty() && !mesh_normals)
            || (!mesh.texcoords.is_empty() && !mesh_texcoords)
        {
            misaligned_meshes += 1;
        }
        if mesh_normals {
            normals.extend(mesh.normals.chunks_exact(3).map(|v| [v[0], v[1], v[2]]));
        } else {
            normals.resize(base + n, [0.0; 3]);
        }
        has_normal.resize(base + n, mesh_normals && n > 0);
        if mesh_texcoords {
            texcoords.extend(mesh.texcoords.chunks_exact(2).map(|v| [v[0], v[1]]));
        } else {
            texcoords.resize(base + n, [0.0; 2]);
        }
        has_texcoord.resize(base + n, mesh_texcoords && n > 0);
        if mesh.indices.iter().any(|&i| i as usize >= n) {
            return Err(invalid(format!(
                "tobj produced an index past the vertices of model `{}`",
                model.name
            )));
        }
        // Faces by their vertex counts (none listed: all triangles).
        let all_triangles = [3u32];
        let arities = if mesh.face_arities.is_empty() {
            &all_triangles[..]
        } else {
            &mesh.face_arities[..]
        };
        let mut at = 0usize;
        let mut face = 0usize;
        let mut push = |t: [u32; 3]| {
            triangles.push(t.map(|i| (base + i as usize) as u32));
            tri_material.push(mesh.material_id);
        };
        while at < mesh.indices.len() {
            let k = arities[face.min(arities.len() - 1)] as usize;
            face += 1;
            let Some(f) = mesh.indices.get(at..at + k) else {
                return Err(invalid(format!(
                    "tobj produced a face past the indices of model `{}`",
                    model.name
                )));
            };
            at += k;
            if k == 3 {
                push([f[0], f[1], f[2]]);
                continue;
            }
            if k < 3 {
                continue;
            }
            let corners: Vec<[f64; 3]> = f
                .iter()
                .map(|&i| {
                    let p = &mesh.positions[3 * i as usize..3 * i as usize + 3];
                    [p[0], p[1], p[2]].map(f64::from)
                })
                .collect();
            let (tris, how) = triangulate::triangulate(&corners);
            match how {
                triangulate::Triangulation::Fan => {}
                triangulate::Triangulation::EarClipped => nonconvex += 1,
                triangulate::Triangulation::Failed => {
                    nonconvex += 1;
                    untriangulated += 1;
                }
            }
            for t in tris {
                push(t.map(|c| f[c]));
            }
        }
    }
    if misaligned_meshes > 0 {
        st.warnings.push(format!(
            "{misaligned_meshes} group(s) have texture coordinates or normals on only some faces; \
             those values were discarded for these groups and filled in"
        ));
    }

    let raw = Raw {
        positions,
        normals,
        has_normal,
        texcoords,
        has_texcoord,
        triangles,
        tri_material,
        repairs: Repairs {
            degenerate_triangles: st.short_faces,
            nonconvex_polygons: nonconvex,
            untriangulated_polygons: untriangulated,
            ..Repairs::default()
        },
    };
    let empty_detail = if st.faces == 0 {
        "the file has no faces".to_owned()
    } else {
        format!(
            "no face has 3 or more vertices ({} point/line faces ignored)",
            st.short_faces
        )
    };
    let all = std::mem::take(&mut st.materials);
    let missing_names = std::mem::take(&mut st.missing_names);
    let known = all.len();
    finish(
        path,
        raw,
        st.warnings,
        Finish {
            empty_detail,
            missing_names,
            known_materials: known,
            bad_vertex: |vertex, p| {
                locate_bad_vertex(path).unwrap_or_else(|| SceneError::Invalid {
                    path: path.to_path_buf(),
                    message: format!(
                        "a vertex has an invalid coordinate {p:?} (merged vertex {vertex}; its \
                         line could not be located)"
                    ),
                })
            },
            resolve: |used: &[usize], warnings: &mut Vec<String>| {
                resolve_materials(&all, used, warnings)
            },
        },
    )
}

/// A scene's geometry as a loader read it, before validation: vertices
/// with per-vertex flags saying which carry a normal or texture coordinate
/// from the file, triangles with a material index into the loader's own
/// list (`None`: the default material), and the repairs made so far.
pub(super) struct Raw {
    pub positions: Vec<[f32; 3]>,
    pub normals: Vec<[f32; 3]>,
    pub has_normal: Vec<bool>,
    pub texcoords: Vec<[f32; 2]>,
    pub has_texcoord: Vec<bool>,
    pub triangles: Vec<[u32; 3]>,
    pub tri_material: Vec<Option<usize>>,
    pub repairs: Repairs,
}

/// What [`finish`] needs from the format: why a scene without triangles
/// is empty, the material names that were used but not defined (with the
/// first line), how many materials the loader knows, the error for a bad
/// vertex, and the materials for the used indices (with the count of
/// textures that failed).
pub(super) struct Finish<B, R> {
    pub empty_detail: String,
    pub missing_names: std::collections::BTreeMap<String, usize>,
    pub known_materials: usize,
    pub bad_vertex: B,
    pub resolve: R,
}

/// Validates and repairs a loader's geometry into a [`Scene`]: bad
/// coordinates rejected, non-finite attributes dropped, degenerate
/// triangles skipped, winding compared with the normals, unused vertices
/// dropped, missing normals filled, materials resolved (those used, in the
/// loader's order, then the default) and albedo clamped; every repair
/// counted and said.
pub(super) fn finish<B, R>(
    path: &Path,
    raw: Raw,
    mut warnings: Vec<String>,
    how: Finish<B, R>,
) -> Result<Scene, SceneError>
where
    B: FnOnce(usize, [f32; 3]) -> SceneError,
    R: FnOnce(&[usize], &mut Vec<String>) -> Result<(Vec<Material>, u64), SceneError>,
{
    let invalid = |message: String| SceneError::Invalid {
        path: path.to_path_buf(),
        message,
    };
    let Raw {
        positions,
        normals,
        mut has_normal,
        texcoords,
        mut has_texcoord,
        triangles,
        tri_material,
        mut repairs,
    } = raw;
    // Every vertex a loader returns is used by some face: reject bad
    // coordinates.
    if let Some((vertex, p)) = positions
        .iter()
        .enumerate()
        .find(|(_, p)| p.iter().any(|&c| coordinate_problem(c).is_some()))
    {
        return Err((how.bad_vertex)(vertex, *p));
    }

    // Non-finite normals or texcoords from the file count as absent.
    let mut bad_attributes = 0usize;
    for (v, n) in normals.iter().enumerate() {
        if has_normal[v] && n.iter().any(|c| !c.is_finite()) {
            has_normal[v] = false;
            bad_attributes += 1;
        }
    }
    for (v, t) in texcoords.iter().enumerate() {
        if has_texcoord[v] && t.iter().any(|c| !c.is_finite()) {
            has_texcoord[v] = false;
            bad_attributes += 1;
        }
    }
    if bad_attributes > 0 {
        warnings.push(format!(
            "{bad_attributes} non-finite normal(s) or texture coordinate(s) were replaced"
        ));
    }

    if triangles.is_empty() {
        return Err(SceneError::Empty {
            path: path.to_path_buf(),
            detail: how.empty_detail,
        });
    }

    // Skip degenerate triangles, check winding against the file's normals.
    let untriangulated = repairs.untriangulated_polygons;
    if untriangulated > 0 {
        warnings.push(format!(
            "{} non-convex polygon face(s) could not be cut into triangles (an outline that \
             crosses itself, or more than {} vertices) and were fanned from their first \
             vertex, which may cover the wrong area: triangulate them in the modelling tool",
            untriangulated,
            triangulate::EAR_CLIPPING_MAX_VERTICES
        ));
    }
    let total = triangles.len();
    let mut kept: Vec<([u32; 3], Option<usize>)> = Vec::with_capacity(total);
    for (tri, mat) in triangles.into_iter().zip(tri_material) {
        let [a, b, c] = tri.map(|v| positions[v as usize].map(f64::from));
        let cross_ab_ac = cross(sub(b, a), sub(c, a));
        let area = 0.5 * norm(cross_ab_ac);
        let longest = dot(sub(b, a), sub(b, a))
            .max(dot(sub(c, b), sub(c, b)))
            .max(dot(sub(a, c), sub(a, c)));
        let repeated = tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2];
        if repeated || area <= DEGENERATE_AREA_RATIO * longest {
            repairs.degenerate_triangles += 1;
            continue;
        }
        if tri.iter().all(|&v| has_normal[v as usize]) {
            let mean = tri
                .iter()
                .map(|&v| normals[v as usize].map(f64::from))
                .fold([0.0; 3], add);
            if dot(cross_ab_ac, mean) < 0.0 {
                repairs.winding_disagrees_with_normals += 1;
            }
        }
        kept.push((tri, mat));
    }
    if kept.is_empty() {
        return Err(SceneError::Empty {
            path: path.to_path_buf(),
            detail: format!("all {total} triangles are degenerate"),
        });
    }
    if repairs.winding_disagrees_with_normals > 0 {
        warnings.push(format!(
            "{} triangle(s) are wound against their vertex normals (kept as they are)",
            repairs.winding_disagrees_with_normals
        ));
    }

    // Drop vertices no kept triangle uses and renumber.
    let mut remap = vec![u32::MAX; positions.len()];
    let mut used: Vec<u32> = Vec::new();
    let mut out_triangles = Vec::with_capacity(kept.len());
    for (tri, _) in &kept {
        out_triangles.push(tri.map(|v| {
            let slot = &mut remap[v as usize];
            if *slot == u32::MAX {
                *slot = used.len() as u32;
                used.push(v);
            }
            *slot
        }));
    }
    let out_positions: Vec<[f32; 3]> = used.iter().map(|&v| positions[v as usize]).collect();
    let any_normal = used.iter().any(|&v| has_normal[v as usize]);
    let any_texcoord = used.iter().any(|&v| has_texcoord[v as usize]);

    let out_normals = if any_normal {
        let flags: Vec<bool> = used.iter().map(|&v| has_normal[v as usize]).collect();
        let given: Vec<[f32; 3]> = used.iter().map(|&v| normals[v as usize]).collect();
        let missing = flags.iter().filter(|&&f| !f).count();
        if missing > 0 {
            warnings.push(format!(
                "{missing} of {} vertices have no usable normal in the file; filled with the \
                 area-weighted mean of their triangles' normals",
                used.len()
            ));
        }
        fill_normals(&out_positions, &out_triangles, given, &flags)
    } else {
        Vec::new()
    };
    let out_texcoords = if any_texcoord {
        let missing = used.iter().filter(|&&v| !has_texcoord[v as usize]).count();
        if missing > 0 {
            warnings.push(format!(
                "{missing} of {} vertices have no usable texture coordinate in the file; set to [0, 0]",
                used.len()
            ));
        }
        used.iter()
            .map(|&v| {
                if has_texcoord[v as usize] {
                    texcoords[v as usize]
                } else {
                    [0.0; 2]
                }
            })
            .collect()
    } else {
        Vec::new()
    };

    // Materials: those used, in tobj's (MTL) order, then the default.
    let mut used_ids: Vec<usize> = kept.iter().filter_map(|(_, m)| *m).collect();
    used_ids.sort_unstable();
    used_ids.dedup();
    if let Some(&bad) = used_ids.iter().find(|&&id| id >= how.known_materials) {
        return Err(invalid(format!(
            "the loader returned an unknown material id {bad}"
        )));
    }
    let needs_default = kept.iter().any(|(_, m)| m.is_none());
    let (mut materials, texture_failures) = (how.resolve)(&used_ids, &mut warnings)?;
    repairs.missing_textures = texture_failures;
    if needs_default {
        materials.push(Material {
            name: DEFAULT_MATERIAL_NAME.to_owned(),
            albedo: [DEFAULT_ALBEDO; 3],
            emission: [0.0; 3],
            kd: [DEFAULT_ALBEDO; 3],
            diffuse_texture: None,
            double_sided: false,
        });
    }
    let default_index = (materials.len() - 1) as u32;
    let mut material_index = vec![u32::MAX; how.known_materials];
    for (k, &id) in used_ids.iter().enumerate() {
        material_index[id] = k as u32;
    }
    let triangle_material: Vec<u32> = kept
        .iter()
        .map(|(_, m)| m.map_or(default_index, |id| material_index[id]))
        .collect();

    for m in &mut materials {
        for c in &mut m.albedo {
            if *c > ALBEDO_MAX {
                *c = ALBEDO_MAX;
                repairs.clamped_albedo_components += 1;
            }
        }
    }
    if repairs.clamped_albedo_components > 0 {
        warnings.push(format!(
            "{} albedo component(s) above {ALBEDO_MAX} were clamped to it",
            repairs.clamped_albedo_components
        ));
    }

    repairs.missing_materials = how.missing_names.len() as u64;
    if !how.missing_names.is_empty() {
        let mut names: Vec<String> = how
            .missing_names
            .iter()
            .take(5)
            .map(|(name, line)| format!("`{name}` (line {line})"))
            .collect();
        if how.missing_names.len() > 5 {
            names.push(format!("and {} more", how.missing_names.len() - 5));
        }
        warnings.push(format!(
            "{} material(s) used but not defined, given the default albedo {DEFAULT_ALBEDO}: {}",
            how.missing_names.len(),
            names.join(", ")
        ));
    }
    if repairs.degenerate_triangles > 0 {
        warnings.push(format!(
            "{} degenerate triangle(s) skipped",
            repairs.degenerate_triangles
        ));
    }

    Ok(Scene {
        source: path.to_path_buf(),
        positions: out_positions,
        normals: out_normals,
        texcoords: out_texcoords,
        triangles: out_triangles,
        triangle_material,
        materials,
        repairs,
        warnings,
        twins: Vec::new(),
        authored: super::Authored::default(),
    })
}

/// Keeps the normals the file gives (`flags`) and fills the others with the
/// area-weighted mean of the adjacent triangles' geometric normals.
fn fill_normals(
    positions: &[[f32; 3]],
    triangles: &[[u32; 3]],
    mut normals: Vec<[f32; 3]>,
    flags: &[bool],
) -> Vec<[f32; 3]> {
    if flags.iter().all(|&f| f) {
        return normals;
    }
    let mut sum = vec![[0.0f64; 3]; positions.len()];
    let mut any = vec![[0.0f64; 3]; positions.len()];
    for tri in triangles {
        let [a, b, c] = tri.map(|v| positions[v as usize].map(f64::from));
        // Twice the area times the unit normal: area weighting for free.
        let n = cross(sub(b, a), sub(c, a));
        for &v in tri {
            let v = v as usize;
            if !flags[v] {
                sum[v] = add(sum[v], n);
                any[v] = n;
            }
        }
    }
    for v in 0..normals.len() {
        if flags[v] {
            continue;
        }
        // Opposite triangles can cancel; fall back to one of them.
        let n = if norm(sum[v]) > 0.0 { sum[v] } else { any[v] };
        let len = norm(n);
        normals[v] = if len > 0.0 {
            n.map(|x| (x / len) as f32)
        } else {
            [0.0, 0.0, 1.0]
        };
    }
    normals
}
