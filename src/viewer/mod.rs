//! The viewer: a window in which the user moves the camera and the lights
//! and watches indirect light follow (issue 12). A `winit` window with a GL
//! 4.5 core context (glutin, EGL on X11), the GL run time
//! ([`crate::gl::renderer::GlRenderer`]) drawing each frame and the
//! tone-mapping pass ([`crate::gl::tonemap`]) putting it on screen. The
//! keys and mouse act through [`controls`], which is tested without a
//! window; the window itself is tested under Xvfb (tests/viewer.rs) with
//! `--frames N --screenshot FILE`, and `--keys` ([`keys`]) presses keys
//! there as a user would.
//!
//! The patch light (direct light on patches and the gather) runs on the
//! GPU or in the CPU run time, whichever the first frame measures faster
//! ([`PatchLight`]): software GL (llvmpipe) computes the gather two orders
//! of magnitude slower than the CPU.
//!
//! Per-pass GPU times (timestamp queries, read when ready) and frames per
//! second are shown in the title bar. Without a display the viewer says so
//! and points to `radiosity render`, which draws the same images headless.

pub mod controls;
pub mod keys;
pub mod objects;
pub mod sky;

use crate::core::scene_config::SceneConfig;
use crate::gl::renderer::{GlOptions, GlRenderer, PASSES};
use crate::gl::tonemap::Tonemap;
use crate::gl::GlError;
use crate::runtime::render::View;
use crate::runtime::Runtime;
use controls::{CameraRig, Edit, LightRig};
use glam::Vec3;
use glutin::config::{ConfigTemplateBuilder, GlConfig};
use glutin::context::{
    ContextApi, ContextAttributesBuilder, GlProfile, NotCurrentGlContext, PossiblyCurrentContext,
    Version,
};
use glutin::display::{GetGlDisplay, GlDisplay};
use glutin::surface::{GlSurface, Surface, SwapInterval, WindowSurface};
use glutin_winit::{DisplayBuilder, GlWindow};
use keys::KeyScript;
use objects::ObjectEdit;
use std::ffi::CString;
use std::num::NonZeroU32;
use std::path::PathBuf;
use std::time::Instant;
use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, EventLoop};
use winit::keyboard::{KeyCode, ModifiersState, PhysicalKey};
use winit::raw_window_handle::HasWindowHandle;
use winit::window::{Window, WindowId};

/// What the viewer shows and where it saves.
pub struct ViewerConfig {
    pub config: SceneConfig,
    /// Where S (with Ctrl) or F5 saves the camera and lights.
    pub save_to: PathBuf,
    pub width: u32,
    pub height: u32,
    /// Render this many frames, then save `screenshot` and exit.
    pub frames: Option<u64>,
    pub screenshot: Option<PathBuf>,
    pub gl: GlOptions,
    /// Fixed exposure (default: automatic from the first frame; E redoes
    /// it).
    pub exposure: Option<f32>,
    pub title: String,
    /// Where each frame's patch light is computed.
    pub patch_light: PatchLight,
    /// Keys pressed one after each drawn frame, before the user's.
    pub keys: KeyScript,
}

/// Where the viewer computes a frame's patch light (direct light on the
/// patches, `B0`, the gather): on the GPU ([`GlRenderer::frame`]), or in
/// the CPU run time with `H` uploaded for the GPU's shading
/// ([`GlRenderer::frame_with_h`]; the shadow maps and the shading stay on
/// the GPU). `Auto` times both on the first frame and keeps the faster:
/// on a software rasterizer (Mesa's llvmpipe) the GL gather of the Cornell
/// box at 4k patches takes about 270 ms against 1 ms on the CPU, on a
/// discrete GPU the GL frame wins.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PatchLight {
    Gpu,
    Cpu,
    Auto,
}

impl PatchLight {
    pub fn parse(s: &str) -> Option<PatchLight> {
        Some(match s {
            "gpu" => PatchLight::Gpu,
            "cpu" => PatchLight::Cpu,
            "auto" => PatchLight::Auto,
            _ => return None,
        })
    }
}

/// Errors of the viewer.
#[derive(Debug, thiserror::Error)]
pub enum ViewerError {
    /// No display to open a window on.
    #[error("no display: {0}")]
    NoDisplay(String),
    /// The window or its GL context could not be made.
    #[error("window: {0}")]
    Window(String),
    #[error(transparent)]
    Gl(#[from] GlError),
    /// A screenshot or the camera/lights file could not be written.
    #[error("{0}")]
    Save(String),
    /// A moving object's mesh could not be loaded.
    #[error("{0}")]
    Objects(String),
}

/// What a run did.
#[derive(Clone, Debug, Default)]
pub struct ViewerReport {
    pub frames: u64,
    pub seconds: f64,
    pub screenshots: Vec<PathBuf>,
    /// The last GPU time of each pass, milliseconds ([`PASSES`] order).
    pub pass_ms: [Option<f64>; 4],
    /// Where the patch light was computed ([`PatchLight::Gpu`] or
    /// [`PatchLight::Cpu`]), and with `Auto` the two frames' times
    /// measured to choose (milliseconds: GPU, CPU).
    pub patch_light: Option<PatchLight>,
    pub chosen_by: Option<(f64, f64)>,
}

/// The keys, printed at start and with H.
pub const HELP: &str = "\
mouse: left drag orbits, right drag looks around, wheel zooms
W A S D Q E: fly (forward, left, back, right, down, up)
1 2 3 4 5: final, direct, indirect, patches, surface-map weights
Tab: next light; arrows, PageUp/PageDown: move it; I J K L: turn it
+ -: brighter, dimmer; [ ]: narrower, wider cone; C: colour
N: add a point light here; B: a spot looking ahead; G: a sun shining ahead; Delete: remove
M: emissive materials off / on; X: automatic exposure again
Y: next sky (the file's, none, sun and sky, overcast, clear); R F: sun up, down; U O: sun round
T: next moving object (arrows, PageUp/PageDown move it, J L turn it), past the last: the lights; V: probe view
P or F12: screenshot; F5 or Ctrl+S: save camera and lights; H: help; Esc: quit";

struct State {
    // Field order is drop order: GL objects go before the context.
    renderer: GlRenderer,
    tonemap: Tonemap,
    gl: glow::Context,
    surface: Surface<WindowSurface>,
    context: PossiblyCurrentContext,
    window: Window,
}

struct App {
    rt: Runtime,
    cfg: ViewerConfig,
    camera: CameraRig,
    lights: LightRig,
    objects: objects::ObjectRig,
    /// The probe view is on, and what the renderer last showed.
    probe_view: bool,
    probe_view_shown: Option<bool>,
    sky: sky::SkyRig,
    /// The sky last given to the run time and the renderer.
    applied_sky: Option<Option<crate::core::sky::Sky>>,
    view: View,
    exposure: Option<f32>,
    state: Option<State>,
    error: Option<ViewerError>,
    report: ViewerReport,
    start: Instant,
    fps_frames: u64,
    fps_start: Instant,
    fps: f64,
    modifiers: ModifiersState,
    /// The patch light's place once chosen, and the CPU run time's last
    /// frame in milliseconds (CPU only).
    patch_light: PatchLight,
    cpu_ms: f64,
    /// The last lights and emission that drew.
    good_lights: Option<(
        Vec<crate::core::scene_config::Light>,
        std::collections::BTreeMap<String, f32>,
    )>,
    drag: Option<MouseButton>,
    cursor: Option<(f64, f64)>,
    screenshot_due: bool,
}

/// Whether a display is named (`DISPLAY` or `WAYLAND_DISPLAY`).
pub fn has_display() -> bool {
    ["DISPLAY", "WAYLAND_DISPLAY"]
        .iter()
        .any(|v| std::env::var_os(v).is_some_and(|s| !s.is_empty()))
}

/// Opens the window and runs until it is closed (or `frames` are drawn).
pub fn run(rt: Runtime, cfg: ViewerConfig) -> Result<ViewerReport, ViewerError> {
    if !has_display() {
        return Err(ViewerError::NoDisplay(
            "DISPLAY is not set (no X server; Wayland desktops provide one through XWayland)"
                .into(),
        ));
    }
    let event_loop = EventLoop::new().map_err(|e| ViewerError::NoDisplay(e.to_string()))?;
    let (lo, hi) = rt.scene.bounds();
    let diagonal = Vec3::from(lo).distance(Vec3::from(hi));
    let emissive = rt
        .scene
        .materials
        .iter()
        .filter(|m| m.emission.iter().any(|&e| e > 0.0))
        .map(|m| m.name.clone())
        .collect();
    let patch_light = cfg.patch_light;
    let mut app = App {
        camera: CameraRig::new(&cfg.config.camera),
        lights: LightRig::new(&cfg.config, diagonal, emissive),
        objects: objects::ObjectRig::new(&cfg.config.objects, diagonal)
            .map_err(|e| ViewerError::Objects(e.to_string()))?,
        probe_view: false,
        probe_view_shown: None,
        sky: sky::SkyRig::new(cfg.config.sky.clone()),
        applied_sky: None,
        view: View::Final,
        exposure: cfg.exposure,
        rt,
        cfg,
        state: None,
        error: None,
        report: ViewerReport::default(),
        start: Instant::now(),
        fps_frames: 0,
        fps_start: Instant::now(),
        fps: 0.0,
        modifiers: ModifiersState::empty(),
        patch_light,
        cpu_ms: 0.0,
        good_lights: None,
        drag: None,
        cursor: None,
        screenshot_due: false,
    };
    if app.cfg.frames.is_none() {
        eprintln!("{HELP}");
    }
    event_loop
        .run_app(&mut app)
        .map_err(|e| ViewerError::Window(e.to_string()))?;
    if let Some(state) = app.state.take() {
        let State {
            mut renderer,
            tonemap,
            gl,
            ..
        } = state;
        // The last frame's GPU times, waited for (the title bar reads them
        // twice a second, so a short session would report none).
        app.report.pass_ms = renderer.pass_times(&gl, true);
        renderer.delete(&gl);
        tonemap.delete(&gl);
    }
    if let Some(e) = app.error {
        return Err(e);
    }
    app.report.seconds = app.start.elapsed().as_secs_f64();
    Ok(app.report)
}

impl App {
    fn create(&mut self, el: &ActiveEventLoop) -> Result<State, ViewerError> {
        let attributes = Window::default_attributes()
            .with_title(self.cfg.title.clone())
            .with_inner_size(PhysicalSize::new(self.cfg.width, self.cfg.height));
        let template = ConfigTemplateBuilder::new();
        let (window, config) = DisplayBuilder::new()
            .with_window_attributes(Some(attributes))
            .build(el, template, |configs| {
                configs
                    .max_by_key(|c| c.num_samples() == 0)
                    .expect("the display lists at least one configuration")
            })
            .map_err(|e| ViewerError::Window(format!("no GL configuration for a window: {e}")))?;
        let window = window.ok_or_else(|| ViewerError::Window("no window was made".into()))?;
        let raw = window.window_handle().ok().map(|h| h.as_raw());
        let display = config.display();
        let attributes = ContextAttributesBuilder::new()
            .with_context_api(ContextApi::OpenGl(Some(Version::new(4, 5))))
            .with_profile(GlProfile::Core)
            .build(raw);
        // SAFETY: the config comes from this display; the window outlives
        // the context (both are held by State, the window dropped last).
        let context = unsafe { display.create_context(&config, &attributes) }
            .map_err(|e| ViewerError::Window(format!("a GL 4.5 core context: {e}")))?;
        let surface_attributes = window
            .build_surface_attributes(Default::default())
            .map_err(|e| ViewerError::Window(e.to_string()))?;
        // SAFETY: as above.
        let surface = unsafe { display.create_window_surface(&config, &surface_attributes) }
            .map_err(|e| ViewerError::Window(format!("a window surface: {e}")))?;
        let context = context
            .make_current(&surface)
            .map_err(|e| ViewerError::Window(format!("making the context current: {e}")))?;
        // Frames as fast as they come when scripted; synchronised to the
        // display otherwise (failure to set it is harmless).
        let interval = if self.cfg.frames.is_some() {
            SwapInterval::DontWait
        } else {
            SwapInterval::Wait(NonZeroU32::MIN)
        };
        let _ = surface.set_swap_interval(&context, interval);
        // SAFETY: the context is current on this thread and outlives `gl`.
        let gl = unsafe {
            glow::Context::from_loader_function(|s| {
                let s = CString::new(s).expect("GL symbol names have no NUL");
                display.get_proc_address(&s)
            })
        };
        let mut renderer = GlRenderer::new(&gl, &self.rt, self.cfg.gl)?;
        if self.patch_light == PatchLight::Auto {
            self.choose_patch_light(&gl, &mut renderer)?;
        }
        self.report.patch_light = Some(self.patch_light);
        let tonemap = Tonemap::new(&gl)?;
        Ok(State {
            renderer,
            tonemap,
            gl,
            surface,
            context,
            window,
        })
    }

    /// Times the first frame both ways (wall clock to `glFinish`, the
    /// GPU's second frame, after its first has compiled and warmed up)
    /// and keeps the faster ([`PatchLight`]).
    fn choose_patch_light(
        &mut self,
        gl: &glow::Context,
        renderer: &mut GlRenderer,
    ) -> Result<(), ViewerError> {
        apply_sky(&mut self.rt, &self.sky, &mut self.applied_sky, gl, renderer);
        let lights = &self.sky.frame_lights(&self.lights.lights);
        let scales = &self.lights.emission;
        let timed = |f: &mut dyn FnMut() -> Result<(), ViewerError>| {
            let t = Instant::now();
            f()?;
            // SAFETY: a finish on the current context.
            unsafe { glow::HasContext::finish(gl) };
            Ok::<f64, ViewerError>(1e3 * t.elapsed().as_secs_f64())
        };
        // GL's frame twice (the first compiles and warms up), the CPU's
        // once (its first computes every term; later ones reuse what did
        // not change); a frame of the other kind between two makes each
        // recompute.
        timed(&mut || {
            renderer.frame(gl, lights, scales)?;
            Ok(())
        })?;
        let rt = &mut self.rt;
        let cpu_ms = timed(&mut || {
            rt.frame(lights, scales);
            renderer.frame_with_h(gl, lights, scales, rt.h(), rt.h_points())?;
            Ok(())
        })?;
        let gpu_ms = timed(&mut || {
            renderer.frame(gl, lights, scales)?;
            Ok(())
        })?;
        self.patch_light = if cpu_ms < gpu_ms {
            PatchLight::Cpu
        } else {
            PatchLight::Gpu
        };
        self.report.chosen_by = Some((gpu_ms, cpu_ms));
        eprintln!(
            "patch light (direct light on patches and the gather) on the {}: a first frame took {gpu_ms:.1} ms on the GPU, {cpu_ms:.1} ms on the CPU",
            if self.patch_light == PatchLight::Cpu { "CPU" } else { "GPU" }
        );
        Ok(())
    }

    /// The frame's patch light where it was chosen to run, and the shadow
    /// maps (nothing when the lights did not change).
    fn light_frame(&mut self) -> Result<(), GlError> {
        let Some(state) = self.state.as_mut() else {
            return Ok(());
        };
        let gl = &state.gl;
        apply_sky(
            &mut self.rt,
            &self.sky,
            &mut self.applied_sky,
            gl,
            &mut state.renderer,
        );
        let lights = self.sky.frame_lights(&self.lights.lights);
        // Moved objects: their triangles to the renderer (the next frame
        // draws their shadows), and the probes they read kept current by
        // the CPU run time (every probe while the probe view is on).
        let moved = self.objects.take_changed();
        if moved {
            state.renderer.set_objects(gl, &self.objects.vertices());
        }
        let view_changed = self.probe_view_shown != Some(self.probe_view);
        if view_changed {
            state.renderer.set_probe_view(gl, self.probe_view);
            self.probe_view_shown = Some(self.probe_view);
        }
        if self.patch_light == PatchLight::Cpu {
            if moved || view_changed {
                let demand = (!self.probe_view).then(|| {
                    let grid = self.rt.baked.probes.grid;
                    let mut d: Vec<usize> = self
                        .objects
                        .bounds()
                        .into_iter()
                        .flat_map(|(lo, hi)| crate::runtime::probes::needed(&grid, lo, hi))
                        .collect();
                    d.sort_unstable();
                    d.dedup();
                    d
                });
                self.rt.set_probe_demand(demand);
            }
            let fs = self.rt.frame(&lights, &self.lights.emission);
            if !fs.unchanged {
                self.cpu_ms = 1e3 * fs.seconds_total;
            }
            state.renderer.frame_with_h(
                gl,
                &lights,
                &self.lights.emission,
                self.rt.h(),
                self.rt.h_points(),
            )?;
            if !fs.unchanged || moved || view_changed {
                state.renderer.set_probe_sh(gl, self.rt.probe_sh());
            }
        } else {
            state.renderer.frame(gl, &lights, &self.lights.emission)?;
        }
        Ok(())
    }

    fn draw(&mut self) -> Result<(), ViewerError> {
        let Some(state) = self.state.as_mut() else {
            return Ok(());
        };
        let size = state.window.inner_size();
        let (w, h) = (size.width.max(1) as usize, size.height.max(1) as usize);
        if let Err(e) = self.light_frame() {
            // A light added beyond what the shadow maps can hold: say so
            // and go back to the last lights that drew, instead of ending
            // the session.
            let recoverable = matches!(
                e,
                GlError::OutOfMemory { .. } | GlError::OverBudget { .. } | GlError::Unsupported(_)
            );
            match self.good_lights.clone() {
                Some((lights, emission)) if recoverable && lights != self.lights.lights => {
                    eprintln!("{e}: the last change is undone");
                    self.lights.lights = lights;
                    self.lights.emission = emission;
                    self.lights.selected = self
                        .lights
                        .selected
                        .min(self.lights.lights.len().saturating_sub(1));
                    self.light_frame()?;
                }
                _ => return Err(e.into()),
            }
        }
        // Kept only when they changed: no copies on the frames that reuse.
        let (lights, emission) = (&self.lights.lights, &self.lights.emission);
        if !self
            .good_lights
            .as_ref()
            .is_some_and(|(l, e)| l == lights && e == emission)
        {
            self.good_lights = Some((lights.clone(), emission.clone()));
        }
        let Some(state) = self.state.as_mut() else {
            return Ok(());
        };
        let gl = &state.gl;
        let camera = self.camera.camera();
        state
            .renderer
            .draw(gl, &camera, self.view, (w, h), &self.lights.emission)?;
        let exposure = match self.exposure {
            Some(k) => k,
            None => {
                let img = state.renderer.read_image(gl);
                let (_, k) = img.to_srgb8(None);
                self.exposure = Some(k);
                k
            }
        };
        let (texture, tsize) = state.renderer.radiance_texture().expect("drawn just above");
        state.tonemap.draw(gl, texture, tsize, exposure, None);
        state
            .surface
            .swap_buffers(&state.context)
            .map_err(|e| ViewerError::Window(format!("presenting the frame: {e}")))?;
        self.report.frames += 1;
        self.fps_frames += 1;
        let since = self.fps_start.elapsed().as_secs_f64();
        if since > 0.5 {
            self.fps = self.fps_frames as f64 / since;
            self.fps_frames = 0;
            self.fps_start = Instant::now();
            let times = state.renderer.pass_times(gl, false);
            self.report.pass_ms = times;
            let passes: Vec<String> = PASSES
                .iter()
                .zip(times)
                // A GPU's passes take tens of microseconds: three
                // decimals below a millisecond.
                .filter_map(|(n, t)| {
                    t.map(|ms| {
                        if ms < 1.0 {
                            format!("{n} {ms:.3} ms")
                        } else {
                            format!("{n} {ms:.1} ms")
                        }
                    })
                })
                .collect();
            let cpu = if self.patch_light == PatchLight::Cpu {
                format!(" | CPU: patch light {:.1} ms", self.cpu_ms)
            } else {
                String::new()
            };
            state.window.set_title(&format!(
                "{} | {:?} | {:.1} fps | GPU: {}{cpu} | {} | {} | H: help",
                self.cfg.title,
                self.view,
                self.fps,
                passes.join(", "),
                self.lights.describe(),
                self.sky.describe()
            ));
        }
        if self.screenshot_due {
            self.screenshot_due = false;
            self.save_screenshot(None)?;
        }
        Ok(())
    }

    fn save_screenshot(&mut self, path: Option<PathBuf>) -> Result<(), ViewerError> {
        let Some(state) = self.state.as_ref() else {
            return Ok(());
        };
        let path =
            path.unwrap_or_else(|| PathBuf::from(format!("screenshot-{}.png", self.report.frames)));
        let img = state.renderer.read_image(&state.gl);
        let (pixels, _) = img.to_srgb8(self.exposure);
        let png = image::RgbImage::from_raw(img.width as u32, img.height as u32, pixels)
            .ok_or_else(|| ViewerError::Save("screenshot size".into()))?;
        png.save(&path)
            .map_err(|e| ViewerError::Save(format!("writing {}: {e}", path.display())))?;
        eprintln!("screenshot: {}", path.display());
        self.report.screenshots.push(path);
        Ok(())
    }

    fn save_config(&self) -> Result<(), ViewerError> {
        let c = SceneConfig {
            camera: self.camera.camera(),
            lights: self.lights.lights.clone(),
            emission: self.lights.emission.clone(),
            sky: self.sky.current(),
            objects: self.objects.placements.clone(),
            ..self.cfg.config.clone()
        };
        c.save(&self.cfg.save_to)
            .map_err(|e| ViewerError::Save(e.to_string()))?;
        eprintln!(
            "saved the camera and lights to {}",
            self.cfg.save_to.display()
        );
        Ok(())
    }

    fn key(&mut self, el: &ActiveEventLoop, code: KeyCode) -> Result<(), ViewerError> {
        let step = self.lights.step;
        let cam = self.camera.clone();
        let turn = 5f32.to_radians();
        let edit = |e: Edit, s: &mut App| s.lights.apply(e, &cam);
        let on_object = self.objects.selected.is_some();
        match code {
            KeyCode::Escape => el.exit(),
            KeyCode::Digit1 => self.view = View::Final,
            KeyCode::Digit2 => self.view = View::Direct,
            KeyCode::Digit3 => self.view = View::Indirect,
            KeyCode::Digit4 => self.view = View::Patches,
            KeyCode::Digit5 => self.view = View::Weights,
            KeyCode::KeyW => self.camera.fly(Vec3::Z, step),
            KeyCode::KeyS if self.modifiers.control_key() => self.save_config()?,
            KeyCode::KeyS => self.camera.fly(Vec3::NEG_Z, step),
            KeyCode::KeyA => self.camera.fly(Vec3::NEG_X, step),
            KeyCode::KeyD => self.camera.fly(Vec3::X, step),
            KeyCode::KeyQ => self.camera.fly(Vec3::NEG_Y, step),
            KeyCode::KeyE => self.camera.fly(Vec3::Y, step),
            KeyCode::Tab => self.lights.select_next(),
            KeyCode::KeyT => {
                self.objects.select_next();
                eprintln!(
                    "{}",
                    match self.objects.selected {
                        Some(_) => self.objects.describe(),
                        None => format!("the keys move lights: {}", self.lights.describe()),
                    }
                );
            }
            KeyCode::KeyV => self.probe_view = !self.probe_view,
            KeyCode::ArrowLeft if on_object => {
                self.objects.apply(ObjectEdit::Move(Vec3::NEG_X), &cam)
            }
            KeyCode::ArrowRight if on_object => self.objects.apply(ObjectEdit::Move(Vec3::X), &cam),
            KeyCode::ArrowUp if on_object => self.objects.apply(ObjectEdit::Move(Vec3::Z), &cam),
            KeyCode::ArrowDown if on_object => {
                self.objects.apply(ObjectEdit::Move(Vec3::NEG_Z), &cam)
            }
            KeyCode::PageUp if on_object => self.objects.apply(ObjectEdit::Move(Vec3::Y), &cam),
            KeyCode::PageDown if on_object => {
                self.objects.apply(ObjectEdit::Move(Vec3::NEG_Y), &cam)
            }
            KeyCode::KeyJ if on_object => self.objects.apply(ObjectEdit::Turn(15.0), &cam),
            KeyCode::KeyL if on_object => self.objects.apply(ObjectEdit::Turn(-15.0), &cam),
            KeyCode::ArrowLeft => edit(Edit::Move(Vec3::NEG_X), self),
            KeyCode::ArrowRight => edit(Edit::Move(Vec3::X), self),
            KeyCode::ArrowUp => edit(Edit::Move(Vec3::Z), self),
            KeyCode::ArrowDown => edit(Edit::Move(Vec3::NEG_Z), self),
            KeyCode::PageUp => edit(Edit::Move(Vec3::Y), self),
            KeyCode::PageDown => edit(Edit::Move(Vec3::NEG_Y), self),
            KeyCode::KeyJ => edit(Edit::Turn(turn, 0.0), self),
            KeyCode::KeyL => edit(Edit::Turn(-turn, 0.0), self),
            KeyCode::KeyI => edit(Edit::Turn(0.0, turn), self),
            KeyCode::KeyK => edit(Edit::Turn(0.0, -turn), self),
            KeyCode::Equal | KeyCode::NumpadAdd => edit(Edit::Scale(1.25), self),
            KeyCode::Minus | KeyCode::NumpadSubtract => edit(Edit::Scale(0.8), self),
            KeyCode::BracketLeft => edit(Edit::Cone(-2.0), self),
            KeyCode::BracketRight => edit(Edit::Cone(2.0), self),
            KeyCode::KeyC => edit(Edit::Colour, self),
            KeyCode::KeyN => edit(Edit::AddPoint, self),
            KeyCode::KeyB => edit(Edit::AddSpot, self),
            KeyCode::KeyG => edit(Edit::AddSun, self),
            KeyCode::Delete | KeyCode::Backspace => edit(Edit::Remove, self),
            KeyCode::KeyM => edit(Edit::ToggleEmission, self),
            KeyCode::KeyX => self.exposure = None,
            KeyCode::KeyP | KeyCode::F12 => self.screenshot_due = true,
            KeyCode::F5 => self.save_config()?,
            KeyCode::KeyH => eprintln!("{HELP}"),
            KeyCode::KeyY => self.sky.next(),
            KeyCode::KeyR => self.sky.move_sun(sky::SUN_STEP_DEG, 0.0),
            KeyCode::KeyF => self.sky.move_sun(-sky::SUN_STEP_DEG, 0.0),
            KeyCode::KeyU => self.sky.move_sun(0.0, -sky::SUN_STEP_DEG),
            KeyCode::KeyO => self.sky.move_sun(0.0, sky::SUN_STEP_DEG),
            _ => {}
        }
        Ok(())
    }

    fn fail(&mut self, el: &ActiveEventLoop, e: ViewerError) {
        self.error = Some(e);
        el.exit();
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, el: &ActiveEventLoop) {
        if self.state.is_some() {
            return;
        }
        match self.create(el) {
            Ok(s) => {
                s.window.request_redraw();
                self.state = Some(s);
            }
            Err(e) => self.fail(el, e),
        }
    }

    fn window_event(&mut self, el: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        match event {
            WindowEvent::CloseRequested => el.exit(),
            WindowEvent::Resized(size) => {
                if let Some(s) = &self.state {
                    s.window.resize_surface(&s.surface, &s.context);
                    let _ = size;
                }
            }
            WindowEvent::ModifiersChanged(m) => self.modifiers = m.state(),
            WindowEvent::KeyboardInput { event, .. } if event.state == ElementState::Pressed => {
                if let PhysicalKey::Code(code) = event.physical_key {
                    if let Err(e) = self.key(el, code) {
                        eprintln!("{e}");
                    }
                }
            }
            WindowEvent::MouseInput { state, button, .. } => {
                self.drag = (state == ElementState::Pressed).then_some(button);
            }
            WindowEvent::CursorMoved { position, .. } => {
                if let (Some(button), Some((x0, y0))) = (self.drag, self.cursor) {
                    let k = 0.005;
                    let (dx, dy) = ((position.x - x0) as f32 * k, (position.y - y0) as f32 * k);
                    match button {
                        MouseButton::Left => self.camera.orbit(dx, dy),
                        _ => self.camera.look(dx, dy),
                    }
                }
                self.cursor = Some((position.x, position.y));
            }
            WindowEvent::MouseWheel { delta, .. } => {
                let lines = match delta {
                    MouseScrollDelta::LineDelta(_, y) => y,
                    MouseScrollDelta::PixelDelta(p) => p.y as f32 / 40.0,
                };
                self.camera.zoom(0.9f32.powf(lines));
            }
            WindowEvent::RedrawRequested => {
                if let Err(e) = self.draw() {
                    self.fail(el, e);
                    return;
                }
                if let Some(n) = self.cfg.frames {
                    if self.report.frames >= n {
                        let path = self.cfg.screenshot.clone();
                        if let Some(p) = path {
                            if let Err(e) = self.save_screenshot(Some(p)) {
                                self.fail(el, e);
                                return;
                            }
                        }
                        el.exit();
                        return;
                    }
                }
                if let Some(code) = self.cfg.keys.next_key() {
                    if let Err(e) = self.key(el, code) {
                        eprintln!("{e}");
                    }
                }
            }
            _ => {}
        }
    }

    fn about_to_wait(&mut self, _el: &ActiveEventLoop) {
        if let Some(s) = &self.state {
            s.window.request_redraw();
        }
    }
}

/// Gives the sky shown to the run time and the renderer when it changed
/// since it was last given; a bake without sky visibility says so once
/// per change (the sky's sun still lights the frame: it is a light).
fn apply_sky(
    rt: &mut Runtime,
    rig: &sky::SkyRig,
    applied: &mut Option<Option<crate::core::sky::Sky>>,
    gl: &glow::Context,
    renderer: &mut GlRenderer,
) {
    let sky = rig.current();
    if applied.as_ref() == Some(&sky) {
        return;
    }
    *applied = Some(sky.clone());
    match rt.set_sky(sky.clone()) {
        Ok(()) => {
            if let Err(e) = renderer.set_sky(gl, rt, sky.as_ref()) {
                eprintln!("{e}");
            }
        }
        Err(e) => eprintln!("{e}"),
    }
}
