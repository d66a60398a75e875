//! Content hashes: the streaming FNV-1a behind [`SceneHash`], the hash of
//! a bake's source scene (OBJ, MTL and textures; a glTF file, its buffer
//! and image files and its textures) that tells whether a bake
//! file still matches its scene.

use super::BakeFileError;
use radiosity_core::scene::{ImageSource, Scene};
use serde::Serialize;
use std::fs::File;
use std::io::{self, Read};
use std::path::{Path, PathBuf};

/// Streaming 64-bit FNV-1a (Fowler, Noll, Vo; offset basis
/// `0xcbf29ce484222325`, prime `0x100000001b3`), used for content hashes of
/// the scene files. Not cryptographic: it identifies an input, it does not
/// defend against a forger. Each step `h ← (h ⊕ b) · p` is a bijection of
/// `h` (the prime is odd), so two inputs of equal length that differ in one
/// byte always hash differently.
#[derive(Clone, Copy, Debug)]
pub struct Fnv1a64 {
    state: u64,
}

impl Default for Fnv1a64 {
    fn default() -> Self {
        Self::new()
    }
}

impl Fnv1a64 {
    /// A fresh hash (of zero bytes): the offset basis.
    pub fn new() -> Fnv1a64 {
        Fnv1a64 {
            state: 0xcbf2_9ce4_8422_2325,
        }
    }

    /// Feeds `bytes`.
    pub fn update(&mut self, bytes: &[u8]) {
        let mut h = self.state;
        for &b in bytes {
            h ^= b as u64;
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
        self.state = h;
    }

    /// The hash of everything fed so far.
    pub fn finish(&self) -> u64 {
        self.state
    }
}

// ---------------------------------------------------------------------------
// The content

/// Content hash of the scene a bake was made from, so a viewer can tell
/// that the scene changed since. Each part is a 64-bit FNV-1a ([`Fnv1a64`]),
/// computed streaming.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct SceneHash {
    /// The OBJ file's bytes.
    pub obj: u64,
    /// The OBJ file's length in bytes.
    pub obj_len: u64,
    /// Every material library named by an `mtllib` line, in the order of
    /// the lines: for each, the name as written, a byte saying whether the
    /// file could be read, its bytes and their count as a `u64`.
    pub mtl: u64,
    /// Every diffuse texture the scene loaded, in material order: its path
    /// relative to the OBJ's directory, its bytes and their count.
    pub textures: u64,
}

impl SceneHash {
    /// Hashes the files `scene` was loaded from: its OBJ, the MTL files the
    /// OBJ names (resolved next to it, as the loader does) and the loaded
    /// diffuse textures. A missing MTL file is hashed as missing (the loader
    /// accepts it with a warning); an unreadable OBJ or texture is an error.
    pub fn of_scene(scene: &Scene) -> Result<SceneHash, BakeFileError> {
        let obj_path = &scene.source;
        let err = |path: &Path| {
            let path = path.to_path_buf();
            move |source| BakeFileError::SceneHash { path, source }
        };
        let dir = obj_path.parent().unwrap_or_else(|| Path::new(""));
        let mut obj = Fnv1a64::new();
        let gltf = radiosity_core::scene::gltf::is_gltf(obj_path);
        let mut libraries: Vec<String> = Vec::new();
        let mut obj_len = 0u64;
        // Stream the scene file once: hash every byte and, for an OBJ,
        // collect `mtllib` names line by line (the name is the rest of the
        // line, trimmed, as tobj reads it).
        let mut file = File::open(obj_path).map_err(err(obj_path))?;
        let mut buf = vec![0u8; 1 << 16];
        let mut line: Vec<u8> = Vec::new();
        loop {
            let k = file.read(&mut buf).map_err(err(obj_path))?;
            if k == 0 {
                break;
            }
            obj.update(&buf[..k]);
            obj_len += k as u64;
            if gltf {
                continue;
            }
            for &b in &buf[..k] {
                if b == b'\n' {
                    collect_mtllib(&line, &mut libraries);
                    line.clear();
                } else if line.len() < 4096 {
                    line.push(b);
                }
            }
        }
        collect_mtllib(&line, &mut libraries);

        // The side files, each as its name and path: an OBJ's material
        // libraries (resolved next to it, as the loader does); a glTF
        // file's buffers and images named by URI, in the file's order
        // (a data URI is in the file's bytes), by their path relative to
        // the file.
        let side: Vec<(String, PathBuf)> = if gltf {
            radiosity_core::scene::files::gltf_side_files(obj_path)
                .map_err(err(obj_path))?
                .into_iter()
                .map(|p| {
                    let rel = p
                        .strip_prefix(dir)
                        .unwrap_or(&p)
                        .to_string_lossy()
                        .into_owned();
                    (rel, p)
                })
                .collect()
        } else {
            libraries
                .into_iter()
                .map(|n| (n.clone(), dir.join(n)))
                .collect()
        };
        let mut mtl = Fnv1a64::new();
        for (name, path) in &side {
            mtl.update(name.as_bytes());
            match File::open(path) {
                Ok(f) if !path.is_dir() => {
                    mtl.update(&[1]);
                    let n = hash_stream(f, &mut mtl).map_err(err(path))?;
                    mtl.update(&n.to_le_bytes());
                }
                _ => mtl.update(&[0]),
            }
        }
        let mut textures = Fnv1a64::new();
        let obj_dir = obj_path.parent().unwrap_or_else(|| Path::new(""));
        for m in &scene.materials {
            match m.diffuse_texture.as_ref().map(|t| &t.image) {
                Some(ImageSource::File(t)) => {
                    // The path relative to the scene file's directory: the
                    // same scene reached through another path hashes the
                    // same.
                    let rel = t.strip_prefix(obj_dir).unwrap_or(t);
                    textures.update(rel.to_string_lossy().as_bytes());
                    let f = File::open(t).map_err(err(t))?;
                    let n = hash_stream(f, &mut textures).map_err(err(t))?;
                    textures.update(&n.to_le_bytes());
                }
                Some(ImageSource::Embedded { label, bytes }) => {
                    textures.update(label.as_bytes());
                    textures.update(bytes);
                    textures.update(&(bytes.len() as u64).to_le_bytes());
                }
                None => {}
            }
        }
        Ok(SceneHash {
            obj: obj.finish(),
            obj_len,
            mtl: mtl.finish(),
            textures: textures.finish(),
        })
    }

    /// The parts that differ from `other` (`"obj"`, `"mtl"`, `"textures"`),
    /// for a message such as "the scene's MTL changed since the bake".
    pub fn differences(&self, other: &SceneHash) -> Vec<&'static str> {
        let mut d = Vec::new();
        if self.obj != other.obj || self.obj_len != other.obj_len {
            d.push("obj");
        }
        if self.mtl != other.mtl {
            d.push("mtl");
        }
        if self.textures != other.textures {
            d.push("textures");
        }
        d
    }

    pub fn to_bytes(self) -> [u8; 32] {
        let mut b = [0u8; 32];
        for (i, v) in [self.obj, self.obj_len, self.mtl, self.textures]
            .iter()
            .enumerate()
        {
            b[8 * i..8 * i + 8].copy_from_slice(&v.to_le_bytes());
        }
        b
    }

    pub fn from_bytes(b: &[u8; 32]) -> SceneHash {
        let v = |i: usize| u64::from_le_bytes(b[8 * i..8 * i + 8].try_into().unwrap());
        SceneHash {
            obj: v(0),
            obj_len: v(1),
            mtl: v(2),
            textures: v(3),
        }
    }
}

/// Adds the library named by `line` if it is an `mtllib` line.
fn collect_mtllib(line: &[u8], out: &mut Vec<String>) {
    if let Some(name) = radiosity_core::scene::files::mtllib_name(&String::from_utf8_lossy(line)) {
        out.push(name.to_string());
    }
}

/// Feeds a whole stream to `h`, returning its length.
fn hash_stream(mut r: impl Read, h: &mut Fnv1a64) -> io::Result<u64> {
    let mut buf = vec![0u8; 1 << 16];
    let mut n = 0u64;
    loop {
        let k = r.read(&mut buf)?;
        if k == 0 {
            return Ok(n);
        }
        h.update(&buf[..k]);
        n += k as u64;
    }
}
