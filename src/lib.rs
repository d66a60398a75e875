//! # radiosity: real-time radiosity from a compressed multi-bounce transfer matrix
//!
//! Global illumination for static diffuse scenes under dynamic lights, after
//! the 2017 thesis this project follows (see `../shared/DESIGN.md`, which fixes
//! the mathematics and the names used in every module).
//!
//! ## Pipeline
//!
//! Bake (offline, OpenCL on any device; every kernel has a CPU reference):
//! 1. [`scene`]: load OBJ + MTL (albedo = `Kd` × linear texture average,
//!    emission = `Ke`), validate, repair what can be repaired and count it.
//! 2. [`voxelize`]: voxel patches — one per occupied voxel and open axis
//!    direction, in the mean plane of its geometry, with that geometry's
//!    projected area (`kernels/voxelize.cl`).
//! 3. [`form_factor`]: form factors `F` between patches with visibility
//!    (`kernels/form_factor.cl`, a BVH of the original triangles, [`bvh`]).
//! 4. [`transfer`]: the multi-bounce transfer `T_k = Σ_{h=1..k} F (diag(ρ)
//!    F)^{h−1}` or `T_∞ = F (I − diag(ρ) F)^{−1}` per colour channel, from
//!    a tiled OpenCL GEMM ([`gemm`], `kernels/gemm.cl`).
//! 5. [`reorder`]: one symmetric permutation of rows and columns that makes
//!    neighbouring rows alike (the thesis's greedy chain, or a Hilbert
//!    curve).
//! 6. [`codec`]: the compressed matrix — BC1 of log-scaled entries, an
//!    exact sparse top fraction, all-zero tiles skipped (or BC4, BC6H, f16,
//!    f32), with its error measured over seeded lights ([`direct`]).
//! 7. [`mesh_map`]: per mesh vertex, up to four patches and weights, never
//!    through a wall.
//! 8. [`bakefile`]: the versioned, checksummed `.rad` file holding all of it.
//!
//! Run time (OpenGL 4.3+): shadow maps → direct irradiance `D` on patches →
//! `H = T · B0` with `B0 = ρ ∘ D + E` → transfer to the mesh → shading.
//!
//! Supporting modules: [`compute`] (the OpenCL layer), [`bake`] (the stages
//! as one call with a report), [`generate`] (bundled scenes), [`scene_config`]
//! (camera and lights files), [`bench`] (benchmarks), [`error`].
//!
//! ## Invariants
//! - Every OpenCL kernel (`kernels/*.cl`, embedded with `include_str!`) has a
//!   Rust CPU reference, and a test compares the two with a tolerance derived
//!   from f32 rounding.
//! - OpenCL code lives in [`compute`] and the stage modules' `cl_*`
//!   functions; the bake never depends on the renderer.
//! - Nothing is silently clamped or dropped: repairs, clamps, slivers and
//!   covered geometry are counted and reported.
//! - The bake is deterministic: the same input and options give the same
//!   result bit for bit (sorted reductions, no atomics on floats), and the
//!   same `.rad` bytes (no times or dates in the file).
//! - A `.rad` file is either rejected with an error naming the file and the
//!   section, or fully valid: the container checks every checksum and
//!   field, and the codec checks every index, offset and value before the
//!   run time may read it.
//! - Albedo components are below 1 ([`scene::ALBEDO_MAX`]), so the
//!   infinite-bounce series converges.
//! - Memory is proportional to occupied voxels, never to the grid volume.

// `!(x > 0.0)` is used on purpose: it is true for NaN, which must fail
// the same checks as non-positive values.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod bake;
pub mod bakefile;
pub mod bench;
pub mod core;
pub mod generate;
pub mod synthetic;
