//! A headless OpenGL 4.5 core context through EGL, without a display or a
//! surface (TOOLCHAIN.md, "OpenGL without a display"): the EGL devices are
//! listed, a hardware one is preferred and Mesa's software rasteriser
//! (llvmpipe, `EGL_MESA_device_software`) is the fallback, so the same code
//! runs on a GPU machine and in the tests here.

use super::GlError;
use glutin::api::egl::context::PossiblyCurrentContext;
use glutin::api::egl::device::Device;
use glutin::api::egl::display::Display;
use glutin::config::{Api, ConfigSurfaceTypes, ConfigTemplateBuilder};
use glutin::context::{ContextApi, ContextAttributesBuilder, GlProfile, Version};
use glutin::prelude::*;
use std::ffi::CString;

/// A current headless context and its GL functions.
pub struct Headless {
    pub gl: glow::Context,
    /// The EGL device's name (vendor and renderer strings of GL follow).
    pub device: String,
    _context: PossiblyCurrentContext,
    _display: Display,
}

impl Headless {
    /// A GL 4.5 core context, current on this thread.
    pub fn new() -> Result<Headless, GlError> {
        let devices: Vec<Device> = Device::query_devices()
            .map_err(|e| GlError::NoDevice(format!("listing EGL devices: {e}")))?
            .collect();
        if devices.is_empty() {
            return Err(GlError::NoDevice(
                "EGL lists no device (install libegl1 libegl-mesa0 libgl1-mesa-dri: \
                 scripts/setup)"
                    .into(),
            ));
        }
        let software = |d: &Device| d.extensions().contains("EGL_MESA_device_software");
        // Hardware first, then software; the first that gives a context.
        let mut order: Vec<&Device> = devices.iter().filter(|d| !software(d)).collect();
        order.extend(devices.iter().filter(|d| software(d)));
        let mut errors = Vec::new();
        for device in order {
            match Self::on(device) {
                Ok(h) => return Ok(h),
                Err(e) => errors.push(e.to_string()),
            }
        }
        Err(GlError::NoDevice(format!(
            "no EGL device gave a GL 4.5 core context: {}",
            errors.join("; ")
        )))
    }

    fn on(device: &Device) -> Result<Headless, GlError> {
        let name = device
            .name()
            .or(device.vendor())
            .unwrap_or("EGL device")
            .to_string();
        let fail =
            |what: &str, e: glutin::error::Error| GlError::Context(format!("{name}: {what}: {e}"));
        // SAFETY: no native display handle is passed; the device outlives
        // the call.
        let display = unsafe { Display::with_device(device, None) }
            .map_err(|e| fail("opening the display", e))?;
        let template = ConfigTemplateBuilder::new()
            .with_surface_type(ConfigSurfaceTypes::empty())
            .with_api(Api::OPENGL)
            .build();
        // SAFETY: the template asks for no surface.
        let config = unsafe { display.find_configs(template) }
            .map_err(|e| fail("listing configurations", e))?
            .next()
            .ok_or_else(|| {
                GlError::Context(format!("{name}: no surfaceless OpenGL configuration"))
            })?;
        let attributes = ContextAttributesBuilder::new()
            .with_context_api(ContextApi::OpenGl(Some(Version::new(4, 5))))
            .with_profile(GlProfile::Core)
            .build(None);
        // SAFETY: no window handle; the config comes from this display.
        let context = unsafe { display.create_context(&config, &attributes) }
            .map_err(|e| fail("creating a GL 4.5 core context", e))?
            .make_current_surfaceless()
            .map_err(|e| fail("making the context current", e))?;
        // SAFETY: the context is current on this thread and stays alive with
        // the functions (both are held by the returned value).
        let gl = unsafe {
            glow::Context::from_loader_function(|s| {
                let s = CString::new(s).expect("GL symbol names have no NUL");
                display.get_proc_address(&s)
            })
        };
        Ok(Headless {
            gl,
            device: name,
            _context: context,
            _display: display,
        })
    }

    /// GL's renderer string (e.g. "llvmpipe (LLVM 15.0.6, 256 bits)").
    pub fn renderer(&self) -> String {
        use glow::HasContext;
        // SAFETY: a plain string query on the current context.
        unsafe { self.gl.get_parameter_string(glow::RENDERER) }
    }
}

/// Whether a `GL_RENDERER` string names a software rasterizer (Mesa's
/// llvmpipe, softpipe and swrast, Google's SwiftShader): GL that runs on
/// the CPU's cores, where the CPU run time and renderer are faster.
pub fn is_software(renderer: &str) -> bool {
    let r = renderer.to_ascii_lowercase();
    ["llvmpipe", "softpipe", "swrast", "swiftshader"]
        .iter()
        .any(|s| r.contains(s))
}

#[cfg(test)]
mod tests {
    use super::is_software;

    /// The renderer strings of the software rasterizers, as their drivers
    /// report them, and of hardware ones.
    #[test]
    fn software_renderers_are_recognised() {
        for r in [
            "llvmpipe (LLVM 15.0.6, 256 bits)",
            "softpipe",
            "Mesa X11 swrast",
            "Google SwiftShader",
        ] {
            assert!(is_software(r), "{r}");
        }
        for r in [
            "NVIDIA H200/PCIe/SSE2",
            "AMD Radeon RX 7900 XTX (radeonsi, navi31, LLVM 17.0.6, DRM 3.54)",
            "Mesa Intel(R) UHD Graphics 630 (CFL GT2)",
        ] {
            assert!(!is_software(r), "{r}");
        }
    }
}
