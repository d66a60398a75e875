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

use super::build::{finish, Finish, Raw};
use super::material::texture_mean_linear;
use super::{
    Authored, DiffuseTexture, ImageSource, Material, Repairs, Scene, Wrap, DEFAULT_ALBEDO,
};
use crate::core::error::SceneError;
use crate::core::scene_config::{Camera, Light};
use accessor::{read_indices, read_vectors, Buffers};
use base64::Engine as _;
use glam::{DMat3, DMat4, DVec3};
use gltf::mesh::Mode;
use gltf::Semantic;
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Luminous efficacy used to turn the lights' photometric units into the
/// run time's radiometric ones: 683 lm/W, the maximum (555 nm) by the SI
/// definition of the candela, the factor Blender's glTF importer uses.
pub const LUMENS_PER_WATT: f64 = 683.0;

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
fn data_uri(uri: &str) -> Option<Result<Vec<u8>, String>> {
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
    let check = crate::core::scene_config::SceneConfig {
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
/// found by `tests/gltf.rs`'s mutations), so that index is checked first.
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
struct Skipped {
    points_lines: usize,
    skinned: usize,
    morphed: usize,
    orthographic: usize,
    ranges: usize,
    missing_texcoords: usize,
    /// Primitives whose texture coordinates were read (not a skip).
    textured: usize,
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

/// Adds one primitive, placed by `world`, to `raw` (errors name it).
fn add_primitive(
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

/// Each material's name, made unique (`name (material 3)` for a repeat;
/// `material 3` without one): the camera-and-lights file's emission map
/// and the reports name materials.
fn material_names(doc: &gltf::Document) -> Vec<String> {
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
/// `tests/gltf.rs`'s mutations).
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
fn resolve_material(
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
                    .map_err(|e| format!("baseColorTexture {}: {e}", t.describe()))?,
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
            .map_err(|e| format!("emissiveTexture {}: {e}", t.describe()))?;
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

/// A `KHR_lights_punctual` light at its node (module doc for units).
fn convert_light(
    l: &gltf::khr_lights_punctual::Light,
    world: &DMat4,
    skipped: &mut Skipped,
) -> Light {
    if l.range().is_some() {
        skipped.ranges += 1;
    }
    let power = l
        .color()
        .map(|c| (f64::from(c) * f64::from(l.intensity()) / LUMENS_PER_WATT) as f32);
    let position = world.transform_point3(DVec3::ZERO).as_vec3().to_array();
    let direction = world
        .transform_vector3(DVec3::NEG_Z)
        .normalize_or_zero()
        .as_vec3()
        .to_array();
    use gltf::khr_lights_punctual::Kind;
    match l.kind() {
        Kind::Directional => Light::Directional {
            direction,
            irradiance: power,
        },
        Kind::Point => Light::Point {
            position,
            intensity: power,
        },
        Kind::Spot {
            inner_cone_angle,
            outer_cone_angle,
        } => Light::Spot {
            position,
            direction,
            intensity: power,
            cone_angle_deg: outer_cone_angle.to_degrees(),
            beam_angle_deg: inner_cone_angle
                .to_degrees()
                .min(outer_cone_angle.to_degrees()),
        },
    }
}

/// A perspective camera at its node: looking down `−z`, `+y` up; the
/// target a unit ahead (moved once the scene's size is known).
fn convert_camera(yfov: f32, world: &DMat4) -> Camera {
    let eye = world.transform_point3(DVec3::ZERO);
    let forward = world.transform_vector3(DVec3::NEG_Z).normalize_or_zero();
    let up = world.transform_vector3(DVec3::Y).normalize_or_zero();
    Camera {
        position: eye.as_vec3().to_array(),
        target: (eye + forward).as_vec3().to_array(),
        up: up.as_vec3().to_array(),
        fov_y_deg: yfov.to_degrees(),
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
