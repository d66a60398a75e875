//! The documentation names no file that does not exist: every repository
//! path written in the README, `docs/`, the shader and kernel READMEs, and
//! the comments of the sources, kernels, shaders, scripts and tests
//! (`crates/bake/src/cut.rs`, `crates/bake/kernels/gemm.cl`, …), and every relative Markdown
//! link. Moved code left such paths behind before (`src/transfer.rs`,
//! `src/codec.rs` named long after the files moved).

use std::path::{Path, PathBuf};

/// Top-level directories whose paths are checked.
const ROOTS: [&str; 8] = [
    "crates", "src", "docs", "scripts", "tests", "examples", "scenes", "fuzz",
];

/// File name endings that make a token a path (a bare directory such as
/// `scenes/NAME/` is a pattern, not a file).
const EXTENSIONS: [&str; 14] = [
    ".rs", ".md", ".cl", ".comp", ".frag", ".vert", ".glsl", ".py", ".json", ".obj", ".mtl",
    ".png", ".svg", ".toml",
];

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Every file under `dir` (recursively), skipping build output.
fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        let name = e.file_name().to_string_lossy().into_owned();
        if name == "target" || name.starts_with('.') {
            continue;
        }
        if p.is_dir() {
            walk(&p, out);
        } else {
            out.push(p);
        }
    }
}

/// Whether a byte may be part of a path token.
fn path_byte(b: u8) -> bool {
    b.is_ascii_alphanumeric() || matches!(b, b'_' | b'-' | b'.' | b'/')
}

/// The repository paths named in `text`: a root directory, a slash, path
/// characters, ending in a known extension; not part of a longer path
/// (`../shared/scenes/…` is outside the repository).
fn named_paths(text: &str) -> Vec<String> {
    let b = text.as_bytes();
    let mut out = Vec::new();
    for root in ROOTS {
        let needle = format!("{root}/");
        let mut from = 0;
        while let Some(k) = text[from..].find(&needle) {
            let at = from + k;
            from = at + needle.len();
            if at > 0 && (path_byte(b[at - 1]) || b[at - 1] == b'$') {
                continue;
            }
            let mut end = at;
            while end < b.len() && path_byte(b[end]) {
                end += 1;
            }
            let token = text[at..end].trim_end_matches(['.', '/']);
            if EXTENSIONS.iter().any(|e| token.ends_with(e)) {
                out.push(token.to_string());
            }
        }
    }
    out
}

/// Relative Markdown link targets (`](path)`, anchors and URLs left out).
fn markdown_links(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut from = 0;
    while let Some(k) = text[from..].find("](") {
        let start = from + k + 2;
        from = start;
        let Some(len) = text[start..].find(')') else {
            break;
        };
        let target = text[start..start + len]
            .split('#')
            .next()
            .unwrap_or("")
            .trim();
        if target.is_empty() || target.contains("://") || target.starts_with("mailto:") {
            continue;
        }
        out.push(target.to_string());
    }
    out
}

#[test]
fn every_path_the_docs_and_comments_name_exists() {
    let root = repo();
    let mut files = Vec::new();
    for dir in [
        "src",
        "docs",
        "scripts",
        "tests",
        "kernels",
        "glsl",
        "examples",
        "scenes",
        "fuzz/fuzz_targets",
    ] {
        walk(&root.join(dir), &mut files);
    }
    files.push(root.join("README.md"));
    let mut missing = Vec::new();
    let mut checked = 0;
    for f in &files {
        let ext = f.extension().and_then(|e| e.to_str()).unwrap_or("");
        let text_like = matches!(
            ext,
            "rs" | "md" | "cl" | "comp" | "frag" | "vert" | "glsl" | "py" | ""
        );
        if !text_like {
            continue;
        }
        let Ok(text) = std::fs::read_to_string(f) else {
            continue;
        };
        let rel = f.strip_prefix(&root).unwrap_or(f).display().to_string();
        // This file's own examples name stale paths on purpose.
        if rel == "tests/docs.rs" {
            continue;
        }
        for p in named_paths(&text) {
            checked += 1;
            if !root.join(&p).exists() {
                missing.push(format!("{rel}: {p}"));
            }
        }
        if ext == "md" {
            let dir = f.parent().unwrap_or(&root);
            for link in markdown_links(&text) {
                checked += 1;
                if !dir.join(&link).exists() {
                    missing.push(format!("{rel}: link {link}"));
                }
            }
        }
    }
    assert!(
        checked > 200,
        "only {checked} paths found: the scan is broken"
    );
    assert!(
        missing.is_empty(),
        "{} path(s) named but missing:\n{}",
        missing.len(),
        missing.join("\n")
    );
}

#[test]
fn the_scan_finds_paths_and_leaves_out_what_is_not_one() {
    let t = "see crates/bake/src/cut.rs, `crates/bake/kernels/gemm.cl`; ../shared/scenes/sponza/sponza.obj \
             and scenes/NAME/ and $OUT/docs/x.md and [a](docs/images/a.png#top)";
    assert_eq!(
        named_paths(t),
        [
            "crates/bake/src/cut.rs",
            "crates/bake/kernels/gemm.cl",
            "docs/images/a.png"
        ]
    );
    assert_eq!(markdown_links(t), ["docs/images/a.png"]);
}
