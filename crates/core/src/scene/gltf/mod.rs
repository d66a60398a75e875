//! glTF 2.0 scenes (`.gltf` with external or data-URI buffers, `.glb`),
//! read through the `gltf` crate, which parses and validates the JSON (every
//! index in range, no unsupported required extension: Draco or meshopt
//! compression is refused by name), into the same [`Scene`] an OBJ gives,
//! through the same checks (`build::finish`).
//!
//! - **Geometry**: every mesh primitive of the default scene (the first
//!   scene when none is the default; the root nodes when the file has no
//!   scene), placed by its node's world transform (composed down the node
//!   tree in `f64`). Triangles as they are; strips and fans cut into
//!   triangles as the spec's section 3.7.2.1 numbers them; points and lines
//!   counted in a warning and left out. A transform with a negative
//!   determinant (a mirror) reverses the winding, so that the front stays
//!   the front; normals go through the inverse transpose. Accessors are
//!   read with every bound checked ([`accessor`]).
//! - **Materials**, as the diffuse model reads them (glTF 2.0 appendix B):
//!   the diffuse albedo is `baseColorFactor × (1 − metallic)` times the
//!   linear mean of `baseColorTexture` (sRGB), with `metallic` the
//!   `metallicFactor` times the mean of the metallic-roughness texture's
//!   blue channel; the texture is kept for shading with its sampler's wrap
//!   modes, its `texCoord` set and `KHR_texture_transform` (applied to the
//!   coordinates here; `v` is flipped to the OBJ convention the run time
//!   samples with). Emission: the glTF emissive value is a radiance, so the
//!   exitance `Ke = π · emissiveFactor · emissive_strength ·` the linear mean
//!   of `emissiveTexture`. `doubleSided` materials are baked two-sided.
//!   What the model cannot show (metal, normal and occlusion maps,
//!   transmission, alpha blending or masking) is said once per material in
//!   the warnings. A primitive without a material gets the OBJ default
//!   albedo ([`DEFAULT_ALBEDO`]), not glTF's white metal, which a diffuse
//!   model would show black.
//! - **Lights and camera** ([`Authored`]): `KHR_lights_punctual` lights
//!   become the run time's, converted from photometric to radiometric units
//!   at [`LUMENS_PER_WATT`] (as Blender's glTF importer does): a point or
//!   spot light of `I` cd has `I / 683` W/sr, a directional light of `E` lx
//!   gives `E / 683` W/m², each times its `color`. A spot's inner and outer
//!   cone angles are the beam and cone angles (the run time's falloff is
//!   linear in angle between them). `range` is ignored (said in a warning):
//!   the falloff is inverse-square to infinity. The first perspective
//!   camera met (scene order) is the start view, looking down its node's
//!   `−z` with `+y` up.
//! - **Units**: metres and `+y` up, as the spec fixes; nothing is rescaled.

pub mod accessor;
mod material;
mod primitive;
mod view;

pub use view::LUMENS_PER_WATT;

use super::build::{finish, Finish, Raw};
use super::{Authored, Material, Repairs, Scene, DEFAULT_ALBEDO};
use crate::error::SceneError;
use crate::scene_config::Camera;
use accessor::Buffers;
use base64::Engine as _;
use glam::{DMat4, DVec3};
use gltf::Semantic;
use material::{material_names, resolve_material};
use primitive::add_primitive;
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use view::{convert_camera, convert_light};

/// Deepest node tree accepted: deeper is a malformed file (or a cycle,
/// which the spec forbids), not a scene.
pub const MAX_NODE_DEPTH: usize = 1024;

/// Whether `path` names a glTF file (`.gltf` or `.glb`, any case).
pub fn is_gltf(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("gltf") || e.eq_ignore_ascii_case("glb"))
}

/// Decodes `%XX` escapes in a URI reference (glTF URIs are
/// percent-encoded: `my%20wall.png`); a malformed escape is kept as written.
pub fn percent_decode(uri: &str) -> String {
    let b = uri.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' && i + 2 < b.len() {
            let hex = std::str::from_utf8(&b[i + 1..i + 3]).ok();
            if let Some(v) = hex.and_then(|h| u8::from_str_radix(h, 16).ok()) {
                out.push(v);
                i += 3;
                continue;
            }
        }
        out.push(b[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// The bytes of a `data:` URI (base64 only, as glTF writers make them).
pub(super) fn data_uri(uri: &str) -> Option<Result<Vec<u8>, String>> {
    let rest = uri.strip_prefix("data:")?;
    let Some((head, data)) = rest.split_once(',') else {
        return Some(Err("a data URI without a comma".to_owned()));
    };
    if !head.ends_with(";base64") {
        return Some(Err(format!(
            "a data URI that is not base64 (`data:{head},...`)"
        )));
    }
    Some(
        base64::engine::general_purpose::STANDARD
            .decode(data.trim())
            .map_err(|e| format!("bad base64 in a data URI: {e}")),
    )
}

/// Loads a glTF scene (module doc). Errors name the file and what is wrong:
/// JSON syntax (with its line), a failed validation (the JSON path of each
/// problem, an unsupported required extension among them), a missing or
/// short buffer, an accessor or index out of range, an image that cannot
/// be decoded.
pub fn load(path: &Path) -> Result<Scene, SceneError> {
    let invalid = |message: String| SceneError::Invalid {
        path: path.to_path_buf(),
        message,
    };
    let bytes = std::fs::read(path).map_err(|source| SceneError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let file = parse(&bytes).map_err(|e| parse_error(path, e))?;
    drop(bytes);
    let doc = &file.document;
    let dir = path.parent().unwrap_or_else(|| Path::new(""));
    let buffers = load_buffers(path, doc, file.blob.as_deref())?;
    let mut warnings: Vec<String> = Vec::new();

    // The nodes to draw: the default scene's, else the first scene's, else
    // every root node.
    let roots: Vec<gltf::Node> = match doc.default_scene().or_else(|| doc.scenes().next()) {
        Some(s) => s.nodes().collect(),
        None => {
            let mut child = vec![false; doc.nodes().len()];
            for n in doc.nodes() {
                for c in n.children() {
                    child[c.index()] = true;
                }
            }
            if doc.meshes().len() > 0 {
                warnings.push("the file has no scene: every root node is drawn".to_owned());
            }
            doc.nodes().filter(|n| !child[n.index()]).collect()
        }
    };
    let mut raw = Raw {
        positions: Vec::new(),
        normals: Vec::new(),
        has_normal: Vec::new(),
        texcoords: Vec::new(),
        has_texcoord: Vec::new(),
        triangles: Vec::new(),
        tri_material: Vec::new(),
        repairs: Repairs::default(),
    };
    let mut authored = Authored::default();
    let mut skipped = Skipped::default();
    let mut seen = vec![false; doc.nodes().len()];
    let mut stack: Vec<(gltf::Node, DMat4, usize)> = roots
        .into_iter()
        .rev()
        .map(|n| (n, DMat4::IDENTITY, 0))
        .collect();
    while let Some((node, parent, depth)) = stack.pop() {
        if depth > MAX_NODE_DEPTH {
            return Err(invalid(format!(
                "node {} is more than {MAX_NODE_DEPTH} levels deep: the node tree is malformed",
                node.index()
            )));
        }
        if std::mem::replace(&mut seen[node.index()], true) {
            return Err(invalid(format!(
                "node {} is reached twice (the spec requires the nodes to form a tree, \
                 without cycles or shared children)",
                node.index()
            )));
        }
        let local = node.transform().matrix().map(|c| c.map(f64::from));
        let world = parent * DMat4::from_cols_array_2d(&local);
        if !world.is_finite() {
            return Err(invalid(format!(
                "node {}: its transform is not finite",
                node.index()
            )));
        }
        if let Some(mesh) = node.mesh() {
            if node.skin().is_some() {
                skipped.skinned += 1;
            }
            if mesh.primitives().any(|p| p.morph_targets().len() > 0) {
                skipped.morphed += 1;
            }
            for prim in mesh.primitives() {
                add_primitive(&mut raw, &prim, &mesh, &world, &buffers, &mut skipped)
                    .map_err(invalid)?;
            }
        }
        if let Some(light) = node.light() {
            authored
                .lights
                .push(convert_light(&light, &world, &mut skipped));
        }
        if let Some(camera) = node.camera() {
            match camera.projection() {
                gltf::camera::Projection::Perspective(p) if authored.camera.is_none() => {
                    authored.camera = Some(convert_camera(p.yfov(), &world));
                }
                gltf::camera::Projection::Orthographic(_) => skipped.orthographic += 1,
                _ => {}
            }
        }
        for child in node.children().collect::<Vec<_>>().into_iter().rev() {
            stack.push((child, world, depth + 1));
        }
    }
    skipped.say(&mut warnings);
    if skipped.textured == 0 {
        // No texture reads coordinates: the scene has none.
        raw.has_texcoord.fill(false);
    }
    if doc.animations().len() > 0 {
        warnings.push(format!(
            "{} animation(s) ignored: the scene is static (drawn as the nodes' transforms place it)",
            doc.animations().len()
        ));
    }
    let empty_detail = if skipped.points_lines > 0 {
        format!(
            "no triangle primitive ({} point or line primitive(s) ignored)",
            skipped.points_lines
        )
    } else {
        "the default scene has no mesh".to_owned()
    };
    let known = doc.materials().len();
    let names = material_names(doc);
    let mut scene = finish(
        path,
        raw,
        warnings,
        Finish {
            empty_detail,
            missing_names: BTreeMap::new(),
            known_materials: known,
            bad_vertex: |vertex, p| SceneError::Invalid {
                path: path.to_path_buf(),
                message: format!(
                    "a vertex has an invalid coordinate {p:?} after its node's transform \
                     (vertex {vertex} of the merged meshes)"
                ),
            },
            resolve: |used: &[usize], warnings: &mut Vec<String>| {
                let materials: Vec<(Material, Vec<String>)> = used
                    .par_iter()
                    .map(|&m| {
                        let mat = doc.materials().nth(m).expect("a used material index");
                        resolve_material(doc, &mat, &names[m], dir, &buffers)
                            .map_err(|e| invalid(format!("material `{}`: {e}", names[m])))
                    })
                    .collect::<Result<_, _>>()?;
                let mut out = Vec::with_capacity(materials.len());
                for (m, notes) in materials {
                    if !notes.is_empty() {
                        warnings.push(format!(
                            "material `{}`: the diffuse model {}",
                            m.name,
                            notes.join("; ")
                        ));
                    }
                    out.push(m);
                }
                Ok((out, 0))
            },
        },
    )?;
    if scene
        .triangle_material
        .iter()
        .any(|&m| scene.materials[m as usize].name == super::DEFAULT_MATERIAL_NAME)
    {
        scene.warnings.push(format!(
            "some primitives have no material: they get the default albedo {DEFAULT_ALBEDO} \
             (glTF's default, white metal, would be black in a diffuse model)"
        ));
    }
    // The camera looks at a point a quarter of the scene's size ahead.
    if let Some(c) = &mut authored.camera {
        let (lo, hi) = scene.bounds();
        let size = (0..3).map(|a| f64::from(hi[a] - lo[a])).fold(0.0, f64::max);
        let d = (0.25 * size).max(1e-3);
        let p = DVec3::from(c.position.map(f64::from));
        let t = DVec3::from(c.target.map(f64::from));
        c.target = (p + (t - p) * d).as_vec3().to_array();
    }
    // The lights and camera must be ones the run time accepts (a node
    // scaled to zero leaves a light without a direction).
    let check = crate::scene_config::SceneConfig {
        sky: None,
        objects: Vec::new(),
        camera: authored.camera.clone().unwrap_or(Camera {
            position: [0.0, 0.0, 1.0],
            target: [0.0; 3],
            up: [0.0, 1.0, 0.0],
            fov_y_deg: 60.0,
        }),
        lights: authored.lights.clone(),
        units: "metres".to_owned(),
        description: String::new(),
        emission: Default::default(),
    };
    if let Err(e) = check.validate() {
        return Err(invalid(format!(
            "the file's {} converts to an invalid one: {e}",
            if e.field.starts_with("camera") {
                "first camera"
            } else {
                "KHR_lights_punctual lights (in scene order)"
            }
        )));
    }
    scene.authored = authored;
    Ok(scene)
}

/// Parses and validates a glTF file's bytes. `gltf-json` 1.4.1's check that
/// a POSITION accessor has `min` and `max` indexes the accessors with the
/// primitive's POSITION index unchecked (a panic on an index out of range,
/// found by the mutations in `tests/gltf/bad.rs`), so that index is checked first.
fn parse(bytes: &[u8]) -> Result<gltf::Gltf, gltf::Error> {
    let unchecked = gltf::Gltf::from_slice_without_validation(bytes)?;
    let blob = unchecked.blob;
    let root = unchecked.document.into_json();
    let accessors = root.accessors.len();
    let mut problems = Vec::new();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            let position = gltf::json::validation::Checked::Valid(Semantic::Positions);
            if let Some(a) = prim.attributes.get(&position) {
                if a.value() >= accessors {
                    let path = gltf::json::Path::new()
                        .field("meshes")
                        .index(m)
                        .field("primitives")
                        .index(p)
                        .field("attributes")
                        .key("POSITION");
                    problems.push((path, gltf::json::validation::Error::IndexOutOfBounds));
                }
            }
        }
    }
    if !problems.is_empty() {
        return Err(gltf::Error::Validation(problems));
    }
    let document = gltf::Document::from_json(root)?;
    Ok(gltf::Gltf { document, blob })
}

/// A glTF parse or validation failure as a scene error.
fn parse_error(path: &Path, e: gltf::Error) -> SceneError {
    match e {
        gltf::Error::Deserialize(j) => SceneError::Parse {
            path: path.to_path_buf(),
            line: j.line(),
            message: format!("not valid glTF JSON: {j}"),
        },
        gltf::Error::Validation(problems) => {
            let mut parts: Vec<String> = problems
                .iter()
                .take(8)
                .map(|(p, err)| {
                    let unsupported = p.as_str().starts_with("extensionsRequired");
                    if unsupported {
                        format!(
                            "{p}: a required extension this loader does not support (such as \
                             Draco or meshopt compression: decompress the file, e.g. with \
                             `gltf-transform copy`)"
                        )
                    } else {
                        format!("{p}: {err}")
                    }
                })
                .collect();
            if problems.len() > 8 {
                parts.push(format!("and {} more", problems.len() - 8));
            }
            SceneError::Invalid {
                path: path.to_path_buf(),
                message: format!("invalid glTF: {}", parts.join("; ")),
            }
        }
        gltf::Error::Io(source) => SceneError::Io {
            path: path.to_path_buf(),
            source,
        },
        other => SceneError::Invalid {
            path: path.to_path_buf(),
            message: format!("not a valid glTF file: {other}"),
        },
    }
}

/// Reads every buffer: the GLB's binary chunk, a data URI or a file beside
/// the glTF; each must hold at least its declared `byteLength`.
fn load_buffers(
    path: &Path,
    doc: &gltf::Document,
    blob: Option<&[u8]>,
) -> Result<Buffers, SceneError> {
    let dir = path.parent().unwrap_or_else(|| Path::new(""));
    let invalid = |message: String| SceneError::Invalid {
        path: path.to_path_buf(),
        message,
    };
    let mut out = Vec::with_capacity(doc.buffers().len());
    for b in doc.buffers() {
        let i = b.index();
        let data = match b.source() {
            gltf::buffer::Source::Bin => blob
                .ok_or_else(|| {
                    invalid(format!(
                        "buffer {i} refers to the binary chunk, which the file does not have"
                    ))
                })?
                .to_vec(),
            gltf::buffer::Source::Uri(uri) => match data_uri(uri) {
                Some(r) => r.map_err(|e| invalid(format!("buffer {i}: {e}")))?,
                None => {
                    let file = dir.join(percent_decode(uri));
                    // A file far larger than declared is read only so far.
                    let meta = std::fs::metadata(&file).map_err(|e| {
                        invalid(format!("buffer {i}: cannot read {} ({e})", file.display()))
                    })?;
                    if meta.len() < b.length() as u64 {
                        return Err(invalid(format!(
                            "buffer {i}: {} has {} bytes, fewer than its byteLength {}",
                            file.display(),
                            meta.len(),
                            b.length()
                        )));
                    }
                    std::fs::read(&file).map_err(|e| {
                        invalid(format!("buffer {i}: cannot read {} ({e})", file.display()))
                    })?
                }
            },
        };
        if data.len() < b.length() {
            return Err(invalid(format!(
                "buffer {i} has {} bytes, fewer than its byteLength {}",
                data.len(),
                b.length()
            )));
        }
        out.push(data);
    }
    Ok(Buffers(out))
}

/// What was left out, counted for one warning each.
#[derive(Default)]
pub(super) struct Skipped {
    points_lines: usize,
    skinned: usize,
    morphed: usize,
    orthographic: usize,
    pub(super) ranges: usize,
    pub(super) missing_texcoords: usize,
    /// Primitives whose texture coordinates were read (not a skip).
    pub(super) textured: usize,
}

impl Skipped {
    /// One warning per kind of thing left out, with its count.
    fn say(&self, w: &mut Vec<String>) {
        let kinds = [
            (
                self.points_lines,
                "point or line primitive(s) ignored (only surfaces take part)",
            ),
            (
                self.skinned,
                "skinned mesh node(s) drawn in their bind pose at their node's transform",
            ),
            (
                self.morphed,
                "mesh(es) with morph targets drawn without them",
            ),
            (
                self.orthographic,
                "orthographic camera(s) ignored (the run time's camera is a pinhole)",
            ),
            (
                self.ranges,
                "light(s) have a range, ignored: the falloff is inverse-square to infinity",
            ),
            (
                self.missing_texcoords,
                "textured primitive(s) lack the texture coordinate set their material's \
                 texture uses: drawn with its mean colour",
            ),
        ];
        for (n, what) in kinds {
            if n > 0 {
                w.push(format!("{n} {what}"));
            }
        }
    }
}

/// The files a glTF file names (buffers and images that are not data
/// URIs), resolved beside it, in the file's order.
pub fn named_files(path: &Path, json: &serde_json::Value) -> Vec<PathBuf> {
    let dir = path.parent().unwrap_or_else(|| Path::new(""));
    let mut out = Vec::new();
    for key in ["buffers", "images"] {
        if let Some(list) = json.get(key).and_then(|v| v.as_array()) {
            for item in list {
                if let Some(uri) = item.get("uri").and_then(|u| u.as_str()) {
                    if !uri.starts_with("data:") {
                        out.push(dir.join(percent_decode(uri)));
                    }
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percent_escapes_decode() {
        assert_eq!(percent_decode("my%20wall.png"), "my wall.png");
        assert_eq!(percent_decode("a%2"), "a%2");
        assert_eq!(percent_decode("%zz"), "%zz");
        assert_eq!(percent_decode("plain.bin"), "plain.bin");
    }

    #[test]
    fn data_uris_decode_base64_only() {
        assert_eq!(
            data_uri("data:application/octet-stream;base64,AAEC")
                .unwrap()
                .unwrap(),
            vec![0, 1, 2]
        );
        assert!(data_uri("data:text/plain,abc").unwrap().is_err());
        assert!(data_uri("file.bin").is_none());
    }
}
