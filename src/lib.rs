//! # radiosity: real-time radiosity from a compressed multi-bounce transfer matrix
//!
//! Global illumination for static diffuse scenes under dynamic lights, after
//! the 2017 thesis this project follows (see `docs/design.md`, which fixes
//! the mathematics and the names used in every module).
//!
//! ## The two phases and their contract
//!
//! ```text
//!            bench ──────────────┐ (measures everything: may import all)
//!              │                 │
//!   bake ──────┼──► bakefile ◄───┼── runtime ◄── gl ◄── viewer
//!    │         │   (the file,    │     │          │        │
//!    │         │    decode-only  │     │          │        │
//!    │         │    codec)       │     │          │        │
//!    └─────────┴───────┬─────────┴─────┴──────────┴────────┘
//!                      ▼
//!                    core  (scene, lights, patches, math, BVH, direct
//!                           light, permutation, .npy, the default camera
//!                           and lights)
//! ```
//!
//! `core`, `bakefile`, `bake` (with the OpenCL layer), `runtime` and `gl`
//! are crates of the workspace (`crates/`), so cargo enforces their edges
//! (`tests/architecture.rs` checks them); this package re-exports them
//! under these names. Which module may import which
//! (`docs/architecture.md` has the same table with the reasons):
//!
//! | module | may import |
//! |---|---|
//! | [`core`] | nothing of ours |
//! | [`bakefile`] (the contract) | `core` |
//! | [`bake`] | `core`, `bakefile` |
//! | [`runtime`] (the CPU frame, the reference; [`runtime::open`] is where an embedding application starts) | `core`, `bakefile` |
//! | [`gl`] (the GPU frame, one file per pass paired with `crates/gl/glsl/<pass>.*`) | `core`, `bakefile`, `runtime` (its definitions: views, images, emission, the gather's column flags) |
//! | [`viewer`] (the window) | `core`, `runtime`, `gl` |
//! | [`mod@reference`] (our path tracer on the original triangles) | `core` |
//! | [`mitsuba`] (the Mitsuba 3 export and its reference images) | `core`, `runtime` (the albedo textures and PFM writer, so the exported `ρ(x)` is the one shaded) |
//! | [`bench`](mod@bench) | everything |
//! | [`synthetic`], [`generate`] (fixtures and bundled scenes) | `core` |
//!
//! The run time never imports a bake stage and the bake never imports the
//! run time: they meet only in the bake file ([`bakefile`]) and its
//! decode-only codec ([`bakefile::codec`]). [`bakefile::baked::Baked`] is a
//! bake as the run time sees it: the file read and validated once, the
//! reordering applied once at load.
//!
//! ## Pipeline
//!
//! Bake (offline, OpenCL on any device; every kernel has a CPU reference),
//! [`bake::run`]:
//! 1. [`core::scene`]: load OBJ + MTL (albedo = `Kd` × linear texture
//!    average, emission = `Ke`) or glTF 2.0 ([`core::scene::gltf`]: the
//!    same diffuse model from the metallic-roughness material, the file's
//!    camera and lights), validate, repair what can be repaired and
//!    count it; [`bake::winding`]: faces the scene sees from behind get a
//!    back side there (recorded in the file, rebuilt by the run time).
//! 2. [`bake::voxelize`]: voxel patches ([`core::patch`]) — one per occupied
//!    voxel and open axis direction, in the mean plane of its geometry, with
//!    that geometry's projected area (`crates/bake/kernels/voxelize.cl`); what cannot be
//!    seen (covered points: [`bake::cover`]) is in no patch; a piece that a
//!    wall thinner than a voxel crosses is first cut along the wall's plane
//!    ([`bake::cut`]; the cut planes go into the surface map); patches far
//!    smaller than a voxel face join a neighbour that shares their light
//!    ([`bake::voxelize::fragments`]).
//! 3. [`bake::form_factor`]: form factors `F` between patches with
//!    visibility (`crates/bake/kernels/form_factor.cl`, a BVH of the original
//!    triangles, [`core::bvh`]).
//! 4. [`bake::transfer`]: the multi-bounce transfer `T_k = Σ_{h=1..k} F
//!    (diag(ρ) F)^{h−1}` or `T_∞ = F (I − diag(ρ) F)^{−1}` per colour
//!    channel, from a tiled OpenCL GEMM ([`bake::gemm`], `crates/bake/kernels/gemm.cl`);
//!    `T_∞` by a blocked LU solve built on the same GEMM ([`bake::solve`]).
//! 5. [`bake::reorder`]: one symmetric permutation of rows and columns that
//!    makes neighbouring rows alike (the thesis's greedy chain, or a Hilbert
//!    curve).
//! 6. [`bake::encode`]: the compressed matrix in the format of
//!    [`bakefile::codec`] — BC1 of log-scaled entries, an exact sparse top
//!    fraction, all-zero tiles skipped (or BC4, BC6H, f16, f32), with its
//!    error measured over seeded lights ([`core::direct`]).
//! 7. [`bake::mesh_map`]: per mesh vertex, up to four patches and weights,
//!    never through a wall; [`bake::surface_map`]: the per-pixel map and the
//!    patches' sample points; [`bake::near_field`]: per patch, its close
//!    neighbours' cells as its rays see them ([`bakefile::near_field`]);
//!    [`bake::probes`]: irradiance probes on a grid in the scene's empty
//!    space, each a sparse transfer from patches, sky cells and emissive
//!    materials to band-2 harmonics ([`bakefile::probes`]).
//! 8. [`bakefile`]: the versioned, checksummed `.rad` file holding all of it
//!    with its typed records ([`bakefile::records`]).
//!
//! Run time (the CPU frame in `runtime`, its GPU twin in `gl`): direct
//! irradiance `D` on patches (at their sample points) → the near-field
//! correction `c` from `D` at close neighbours' points → `H = T̃ · (B0 + ρ
//! ∘ c) + c` with `B0 = ρ ∘ D + E` straight from the compressed matrix →
//! `H` at every pixel through the surface map → shading
//! `L = ρ/π · (D + H) + Le`.
//!
//! Moving objects ([`core::objects`]) take `ρ/π · (D + E_probes)`, the
//! probes updated from `B0 − E + ρ ∘ H` ([`runtime::probes`]) and looked up
//! with a shadow ray to each so that no light leaks through a wall; they
//! cast shadows in the shadow maps and leave the patches' light as it is.
//!
//! ## Invariants
//! - Every OpenCL kernel (`crates/bake/kernels/*.cl`, embedded with `include_str!`) has a
//!   Rust CPU reference, and a test compares the two with a tolerance derived
//!   from f32 rounding. Every GLSL shader (`crates/gl/glsl/`) has one in [`runtime`]
//!   or [`core`] (`crates/gl/glsl/README.md` pairs them; tests/gl_gather.rs and
//!   tests/gl_render.rs compare them).
//! - OpenCL code lives in [`core::compute`] and the stage modules' `cl_*`
//!   functions; GL code lives in [`gl`] and the window in [`viewer`], which
//!   import the run time and the contract, never a bake stage.
//! - No import cycle between modules; types shared by several stages live in
//!   [`core`] (the patch, its frame, the permutation), not in the first stage
//!   that needed them.
//! - Nothing is silently clamped or dropped: repairs, clamps, slivers and
//!   covered geometry are counted and reported.
//! - The bake is deterministic: the same input and options give the same
//!   result bit for bit (sorted reductions, no atomics on floats), and the
//!   same `.rad` bytes (no times or dates in the file).
//! - A `.rad` file is either rejected with an error naming the file and the
//!   section, or fully valid: the container checks every checksum and
//!   field, the records their schema and version, and the codec every
//!   index, offset and value before the run time may read it.
//! - Library errors are typed ([`bake::error::BakeError`],
//!   [`bakefile::BakeFileError`] with [`bakefile::SectionError`] inside,
//!   [`bakefile::baked::LoadError`], [`runtime::open::OpenError`],
//!   [`core::error`]) and name options and values, never command-line
//!   flags; `anyhow` is the binary's alone.
//! - Albedo components are below 1 ([`core::scene::ALBEDO_MAX`]), so the
//!   infinite-bounce series converges.
//! - Memory is proportional to occupied voxels, never to the grid volume.

// `!(x > 0.0)` is used on purpose: it is true for NaN, which must fail
// the same checks as non-positive values.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub use radiosity_bake as bake;
pub use radiosity_bakefile as bakefile;
pub mod bench;
pub use radiosity_gl as gl;
pub use radiosity_runtime as runtime;
pub mod generate;
pub mod mitsuba;
pub mod reference;
pub mod synthetic;
pub mod viewer;

/// The shared core (`radiosity-core`), with the OpenCL layer the bake
/// crate holds (`radiosity_bake::compute`) at its former path.
pub mod core {
    pub use radiosity_bake::compute;
    pub use radiosity_core::*;
}
