//! The scene's triangles on the GPU, drawn by the shadow and shading
//! passes: one vertex buffer of the front triangles expanded to three
//! vertices each (position, texture coordinates, triangle index), sorted by
//! material so that each material is one draw with its albedo texture
//! bound; every triangle's geometric normal in a storage buffer (the
//! shading pass's normal, as the CPU renderer's); and each material's
//! `map_Kd` as an sRGB texture with mipmaps (its CPU counterpart is
//! [`radiosity_runtime::texture`], sampled bilinearly without mipmaps: the
//! two agree where a texel covers a pixel or more).
//!
//! A two-sided bake's scene holds the back-side twins after the front
//! triangles ([`radiosity_core::scene::Scene::with_back_sides`]); only the
//! front half is drawn (the twins are coincident) and the shading pass
//! swaps to the twin where it sees a front triangle from behind.

use super::{bytes_of, storage_buffer, GlError};
use glow::HasContext;
use radiosity_core::scene::Scene;

/// Bytes per expanded vertex: position (3 f32), texture coordinates
/// (2 f32), triangle index (u32).
pub const VERTEX_BYTES: usize = 24;

/// One material's draw.
#[derive(Clone, Debug)]
pub struct Draw {
    pub material: usize,
    pub first_vertex: usize,
    pub vertices: usize,
}

/// The scene on the GPU.
pub struct GlScene {
    pub vao: glow::VertexArray,
    vbo: glow::Buffer,
    /// Positions only, indexed, for the depth-only passes (shadow maps,
    /// the shading's depth pre-pass): each vertex once (12 bytes) instead
    /// of three times per triangle with its texture coordinates (24), and
    /// shared vertices transformed once by the post-transform cache.
    depth_vao: glow::VertexArray,
    depth_vbo: glow::Buffer,
    depth_ebo: glow::Buffer,
    /// Four words per triangle (every triangle, twins included): the unit
    /// normal and the twin's index as float bits (`u32::MAX`: none).
    pub normals: glow::Buffer,
    pub draws: Vec<Draw>,
    /// Per material: its albedo texture, when it has one and the scene has
    /// texture coordinates.
    pub textures: Vec<Option<glow::Texture>>,
    /// The scene's own triangles (drawn), and all triangles (twins
    /// included).
    pub drawn: usize,
    pub triangles: usize,
    /// Bounds of the scene.
    pub lo: [f32; 3],
    pub hi: [f32; 3],
}

impl GlScene {
    /// Uploads `scene`: its own triangles are drawn, its twins (back sides,
    /// `Scene::twins`) are found through their originals when seen from
    /// behind. The context must be current.
    pub fn new(gl: &glow::Context, scene: &Scene) -> Result<GlScene, GlError> {
        let triangles = scene.triangles.len();
        let drawn = scene.own_triangles();
        let mut order: Vec<usize> = (0..drawn).collect();
        order.sort_by_key(|&t| scene.triangle_material[t]);
        let has_uv = !scene.texcoords.is_empty();
        let mut words: Vec<u32> = Vec::with_capacity(drawn * 3 * VERTEX_BYTES / 4);
        let mut draws: Vec<Draw> = Vec::new();
        for (k, &t) in order.iter().enumerate() {
            let m = scene.triangle_material[t] as usize;
            match draws.last_mut() {
                Some(d) if d.material == m => d.vertices += 3,
                _ => draws.push(Draw {
                    material: m,
                    first_vertex: 3 * k,
                    vertices: 3,
                }),
            }
            for v in scene.triangles[t] {
                let p = scene.positions[v as usize];
                let uv = if has_uv {
                    scene.texcoords[v as usize]
                } else {
                    [0.0; 2]
                };
                words.extend([p[0], p[1], p[2], uv[0], uv[1]].map(f32::to_bits));
                words.push(t as u32);
            }
        }
        // Per triangle its normal and its twin's index (`u32::MAX` for
        // none), the fourth word as float bits.
        let normals: Vec<f32> = (0..triangles)
            .flat_map(|t| {
                let [x, y, z] = scene.triangle_normal(t).map(|c| c as f32);
                let twin = scene.twin(t).map_or(u32::MAX, |k| k as u32);
                [x, y, z, f32::from_bits(twin)]
            })
            .collect();
        let (lo, hi) = scene.bounds();
        // SAFETY: object creation and uploads on the current context; the
        // attribute layout matches VERTEX_BYTES.
        unsafe {
            let vao = gl.create_vertex_array().map_err(GlError::Call)?;
            let vbo = gl.create_buffer().map_err(GlError::Call)?;
            gl.bind_vertex_array(Some(vao));
            gl.bind_buffer(glow::ARRAY_BUFFER, Some(vbo));
            let data = bytes_of(&words);
            let data = if data.is_empty() { &[0u8; 4][..] } else { data };
            gl.buffer_data_u8_slice(glow::ARRAY_BUFFER, data, glow::STATIC_DRAW);
            let stride = VERTEX_BYTES as i32;
            gl.enable_vertex_attrib_array(0);
            gl.vertex_attrib_pointer_f32(0, 3, glow::FLOAT, false, stride, 0);
            gl.enable_vertex_attrib_array(1);
            gl.vertex_attrib_pointer_f32(1, 2, glow::FLOAT, false, stride, 12);
            gl.enable_vertex_attrib_array(2);
            gl.vertex_attrib_pointer_i32(2, 1, glow::UNSIGNED_INT, stride, 20);
            gl.bind_vertex_array(None);
            // The depth passes' geometry: the drawn triangles' indices
            // into the scene's positions.
            let depth_vao = gl.create_vertex_array().map_err(GlError::Call)?;
            let depth_vbo = gl.create_buffer().map_err(GlError::Call)?;
            let depth_ebo = gl.create_buffer().map_err(GlError::Call)?;
            gl.bind_vertex_array(Some(depth_vao));
            let positions: Vec<f32> = scene.positions.iter().flatten().copied().collect();
            let indices: Vec<u32> = scene.triangles[..drawn].iter().flatten().copied().collect();
            let nonempty = |d: &[u8]| -> Vec<u8> {
                if d.is_empty() {
                    vec![0u8; 4]
                } else {
                    d.to_vec()
                }
            };
            gl.bind_buffer(glow::ARRAY_BUFFER, Some(depth_vbo));
            gl.buffer_data_u8_slice(
                glow::ARRAY_BUFFER,
                &nonempty(bytes_of(&positions)),
                glow::STATIC_DRAW,
            );
            gl.enable_vertex_attrib_array(0);
            gl.vertex_attrib_pointer_f32(0, 3, glow::FLOAT, false, 12, 0);
            gl.bind_buffer(glow::ELEMENT_ARRAY_BUFFER, Some(depth_ebo));
            gl.buffer_data_u8_slice(
                glow::ELEMENT_ARRAY_BUFFER,
                &nonempty(bytes_of(&indices)),
                glow::STATIC_DRAW,
            );
            gl.bind_vertex_array(None);
            let normals = storage_buffer(gl, bytes_of(&normals), glow::STATIC_DRAW)?;
            let mut textures = Vec::with_capacity(scene.materials.len());
            for m in &scene.materials {
                let tex = match (&m.diffuse_texture, has_uv) {
                    (Some(t), true) => match t.decode() {
                        Ok(img) => Some(upload_texture(gl, &img.to_rgb8(), t.wrap)?),
                        // The loader counted it as missing; the CPU
                        // renderer uses the material's albedo too.
                        Err(_) => None,
                    },
                    _ => None,
                };
                textures.push(tex);
            }
            super::check(gl, "uploading the scene")?;
            Ok(GlScene {
                vao,
                vbo,
                depth_vao,
                depth_vbo,
                depth_ebo,
                normals,
                draws,
                textures,
                drawn,
                triangles,
                lo,
                hi,
            })
        }
    }

    /// Draws every drawn (front) triangle's positions only (indexed: the
    /// depth passes' geometry, no textures), with the bound program.
    pub fn draw_depth(&self, gl: &glow::Context) {
        // SAFETY: a draw of this scene's index buffer on the current
        // context.
        unsafe {
            gl.bind_vertex_array(Some(self.depth_vao));
            gl.draw_elements(
                glow::TRIANGLES,
                (3 * self.drawn) as i32,
                glow::UNSIGNED_INT,
                0,
            );
            gl.bind_vertex_array(None);
        }
    }

    /// Frees the GPU objects.
    pub fn delete(self, gl: &glow::Context) {
        // SAFETY: objects of this context, not used after.
        unsafe {
            gl.delete_vertex_array(self.vao);
            gl.delete_buffer(self.vbo);
            gl.delete_vertex_array(self.depth_vao);
            gl.delete_buffer(self.depth_vbo);
            gl.delete_buffer(self.depth_ebo);
            gl.delete_buffer(self.normals);
            for t in self.textures.into_iter().flatten() {
                gl.delete_texture(t);
            }
        }
    }
}

/// An sRGB texture with mipmaps, rows as stored in the file (top first:
/// OBJ's `v` is up, so the shader samples at `(u, 1 − v)`, as the CPU's
/// [`radiosity_runtime::texture::Texture::sample`] does).
fn upload_texture(
    gl: &glow::Context,
    img: &image::RgbImage,
    wrap: [radiosity_core::scene::Wrap; 2],
) -> Result<glow::Texture, GlError> {
    // SAFETY: texture creation and an upload of w × h RGB bytes.
    unsafe {
        let t = gl.create_texture().map_err(GlError::Call)?;
        gl.bind_texture(glow::TEXTURE_2D, Some(t));
        gl.pixel_store_i32(glow::UNPACK_ALIGNMENT, 1);
        gl.tex_image_2d(
            glow::TEXTURE_2D,
            0,
            glow::SRGB8 as i32,
            img.width() as i32,
            img.height() as i32,
            0,
            glow::RGB,
            glow::UNSIGNED_BYTE,
            glow::PixelUnpackData::Slice(Some(img.as_raw())),
        );
        gl.generate_mipmap(glow::TEXTURE_2D);
        let p = |k: u32, v: u32| gl.tex_parameter_i32(glow::TEXTURE_2D, k, v as i32);
        p(glow::TEXTURE_MIN_FILTER, glow::LINEAR_MIPMAP_LINEAR);
        p(glow::TEXTURE_MAG_FILTER, glow::LINEAR);
        p(glow::TEXTURE_WRAP_S, wrap[0].gl());
        p(glow::TEXTURE_WRAP_T, wrap[1].gl());
        Ok(t)
    }
}
