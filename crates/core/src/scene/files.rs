//! The files a scene is made of: a glTF file and the buffers and images it
//! names ([`gltf_side_files`]), or an OBJ, the MTL libraries the OBJ names
//! (`mtllib`, resolved beside the OBJ as the loader resolves them) and the
//! image files those name (`map_Kd`, which the loader reads, and every
//! other map an MTL may name: the files a user keeps with the model). The
//! commands list them so that none of their outputs is ever one of these
//! (a careless `-o scene.obj` or `-o scene.mtl` must not destroy the
//! model), and the bake file's scene hash finds the MTL libraries the same
//! way ([`mtllib_name`]). Found by a scan of the lines alone, without
//! loading the scene: a check that runs before any work.

use super::material::texture_file_name;
use std::fs::File;
use std::io::{self, BufRead, BufReader};
use std::path::{Path, PathBuf};

/// The library named by an OBJ line `mtllib NAME` (the rest of the line,
/// trimmed, as tobj reads it), if the line is one.
pub fn mtllib_name(line: &str) -> Option<&str> {
    let line = line.trim_end_matches('\r');
    if line.split_whitespace().next() != Some("mtllib") {
        return None;
    }
    Some(line.split_once(' ').unwrap_or_default().1.trim())
}

/// Whether an MTL keyword names an image file: `map_Kd` and the other
/// `map_*` keywords, and `bump`, `disp`, `decal`, `refl`, `norm`.
fn is_map_keyword(k: &str) -> bool {
    k.starts_with("map_") || matches!(k, "bump" | "disp" | "decal" | "refl" | "norm")
}

/// The OBJ at `obj`, the MTL libraries it names that exist, and the image
/// files those name (resolved relative to their MTL, as the loader
/// resolves `map_Kd`), in the order found, without repeats. A library or
/// image that does not exist is left out (nothing could overwrite it
/// unnoticed that the loader reads); an OBJ that cannot be read is the
/// error.
pub fn source_files(obj: &Path) -> io::Result<Vec<PathBuf>> {
    if super::gltf::is_gltf(obj) {
        let mut files = vec![obj.to_path_buf()];
        for f in gltf_side_files(obj)? {
            if f.is_file() {
                push_new(&mut files, f);
            }
        }
        return Ok(files);
    }
    let mut files = vec![obj.to_path_buf()];
    let dir = obj.parent().unwrap_or_else(|| Path::new(""));
    let mut libraries = Vec::new();
    // Lines as bytes: an OBJ need not be UTF-8 (the loader decodes lossily).
    let mut reader = BufReader::with_capacity(1 << 16, File::open(obj)?);
    let mut line = Vec::new();
    loop {
        line.clear();
        if reader.read_until(b'\n', &mut line)? == 0 {
            break;
        }
        // `mtllib` lines are short; a long line is geometry.
        if line.len() < 4096 && line.starts_with(b"mtllib") {
            let text = String::from_utf8_lossy(&line);
            if let Some(name) = mtllib_name(text.trim_end_matches('\n')) {
                libraries.push(dir.join(name));
            }
        }
    }
    for lib in libraries {
        let Ok(f) = File::open(&lib) else { continue };
        if lib.is_dir() {
            continue;
        }
        let lib_dir = lib.parent().unwrap_or_else(|| Path::new("")).to_path_buf();
        push_new(&mut files, lib.clone());
        for l in BufReader::new(f).split(b'\n').map_while(Result::ok) {
            let text = String::from_utf8_lossy(&l);
            let text = text.trim();
            let mut words = text.splitn(2, char::is_whitespace);
            let (Some(key), Some(rest)) = (words.next(), words.next()) else {
                continue;
            };
            if !is_map_keyword(key) {
                continue;
            }
            let name = texture_file_name(rest);
            if !name.is_empty() {
                let path = lib_dir.join(name);
                if path.is_file() {
                    push_new(&mut files, path);
                }
            }
        }
    }
    Ok(files)
}

/// The files a glTF file names (its buffers' and images' URIs that are not
/// data URIs, resolved beside it), in the file's order, whether or not they
/// exist. Reads only the JSON (a `.glb`'s first chunk); a file whose JSON
/// cannot be read names none (loading it reports why), one that cannot be
/// opened is the error.
pub fn gltf_side_files(path: &Path) -> io::Result<Vec<PathBuf>> {
    use std::io::Read;
    let mut f = File::open(path)?;
    let mut head = [0u8; 20];
    let n = f.read(&mut head)?;
    let json: Vec<u8> = if n >= 20 && &head[0..4] == b"glTF" {
        // GLB: header (magic, version, length), then the JSON chunk
        // (length, type "JSON", data).
        let len = u32::from_le_bytes([head[12], head[13], head[14], head[15]]) as u64;
        let size = f.metadata()?.len();
        if &head[16..20] != b"JSON" || len > size {
            return Ok(Vec::new());
        }
        let mut buf = vec![0u8; len as usize];
        if f.read_exact(&mut buf).is_err() {
            return Ok(Vec::new());
        }
        buf
    } else {
        let mut buf = head[..n].to_vec();
        f.read_to_end(&mut buf)?;
        buf
    };
    let Ok(value) = serde_json::from_slice::<serde_json::Value>(&json) else {
        return Ok(Vec::new());
    };
    Ok(super::gltf::named_files(path, &value))
}

fn push_new(files: &mut Vec<PathBuf>, p: PathBuf) {
    if !files.contains(&p) {
        files.push(p);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_obj_its_libraries_and_their_maps() {
        let dir = std::env::temp_dir().join(format!("radiosity-files-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(dir.join("tex")).unwrap();
        std::fs::write(
            dir.join("a.obj"),
            "mtllib a.mtl\nmtllib missing.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
        )
        .unwrap();
        std::fs::write(
            dir.join("a.mtl"),
            "newmtl m\nKd 1 1 1\nmap_Kd -bm 0.5 tex\\d.png\nmap_bump tex/b.png\nbump tex/b.png\nmap_Ks gone.png\n",
        )
        .unwrap();
        std::fs::write(dir.join("tex/d.png"), b"x").unwrap();
        std::fs::write(dir.join("tex/b.png"), b"x").unwrap();
        let files = source_files(&dir.join("a.obj")).unwrap();
        assert_eq!(
            files,
            vec![
                dir.join("a.obj"),
                dir.join("a.mtl"),
                dir.join("tex/d.png"),
                dir.join("tex/b.png")
            ]
        );
        assert!(source_files(&dir.join("nothing.obj")).is_err());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
