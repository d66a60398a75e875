//! Build script: `intel_tex_2`'s ISPC kernels are C++ objects and need the
//! C++ runtime at link time (TOOLCHAIN.md: otherwise `__gxx_personality_v0`
//! is undefined). Kernels and shaders are embedded with `include_str!`, so
//! cargo already rebuilds when they change.
fn main() {
    println!("cargo:rustc-link-lib=dylib=stdc++");
    println!("cargo:rerun-if-changed=build.rs");
}
