//! The OpenCL layer: device discovery (once per process), device choice,
//! program builds that return the compiler log, buffers checked against the
//! device's limits, and kernel timing from profiling events.
//!
//! Every bake stage that runs on OpenCL goes through [`Gpu`]; no other module
//! touches `opencl3` directly except to set kernel arguments. The bake must
//! run on any OpenCL 1.2 device, PoCL on the CPU included (TOOLCHAIN.md), so
//! kernels avoid float atomics and OpenCL 2.0 features.

use opencl3::command_queue::{CommandQueue, CL_QUEUE_PROFILING_ENABLE};
use opencl3::context::Context;
use opencl3::device::{
    Device, CL_DEVICE_TYPE_ACCELERATOR, CL_DEVICE_TYPE_ALL, CL_DEVICE_TYPE_CPU, CL_DEVICE_TYPE_GPU,
};
use opencl3::event::Event;
use opencl3::kernel::Kernel;
use opencl3::memory::{Buffer, CL_MEM_READ_ONLY, CL_MEM_READ_WRITE, CL_MEM_WRITE_ONLY};
use opencl3::program::Program;
use opencl3::types::{cl_mem_flags, CL_BLOCKING};
use radiosity_core::error::ClError;
use serde::Serialize;
use std::sync::OnceLock;

/// The environment variable that selects an OpenCL device by index, like
/// `--device INDEX` (the flag wins when both are given).
pub const DEVICE_ENV: &str = "RADIOSITY_CL_DEVICE";

/// What the user learns about a device, and what stages size their work by.
#[derive(Clone, Debug, Serialize)]
pub struct DeviceInfo {
    /// Index in the flattened list of all devices of all platforms.
    pub index: usize,
    pub platform: String,
    pub name: String,
    pub vendor: String,
    /// "GPU", "CPU", "accelerator" or "other".
    pub kind: String,
    pub version: String,
    pub opencl_c_version: String,
    pub driver_version: String,
    pub compute_units: u32,
    pub max_work_group_size: usize,
    pub max_mem_alloc_bytes: u64,
    pub global_mem_bytes: u64,
    pub local_mem_bytes: u64,
    pub fp64: bool,
}

struct Discovered {
    devices: Vec<(Device, DeviceInfo)>,
}

/// Enumerates platforms and devices exactly once per process: PoCL returns
/// empty device lists to concurrent first calls (TOOLCHAIN.md), and parallel
/// tests would otherwise race.
fn discovered() -> Result<&'static Discovered, ClError> {
    static CELL: OnceLock<Result<Discovered, String>> = OnceLock::new();
    CELL.get_or_init(discover)
        .as_ref()
        .map_err(|e| ClError::NoPlatform(e.clone()))
}

fn discover() -> Result<Discovered, String> {
    let platforms =
        opencl3::platform::get_platforms().map_err(|e| format!("clGetPlatformIDs failed: {e}"))?;
    if platforms.is_empty() {
        return Err("the OpenCL loader found no platform".into());
    }
    let mut devices = Vec::new();
    for platform in &platforms {
        let platform_name = platform.name().unwrap_or_else(|_| "?".into());
        // A platform without devices reports an error; that is not fatal
        // while another platform has devices.
        let Ok(ids) = platform.get_devices(CL_DEVICE_TYPE_ALL) else {
            continue;
        };
        for id in ids {
            let device = Device::new(id);
            let info = describe(&device, devices.len(), &platform_name);
            devices.push((device, info));
        }
    }
    if devices.is_empty() {
        return Err(format!(
            "{} platform(s) but no device: {}",
            platforms.len(),
            platforms
                .iter()
                .map(|p| p.name().unwrap_or_default())
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    Ok(Discovered { devices })
}

fn describe(device: &Device, index: usize, platform: &str) -> DeviceInfo {
    let kind = match device.dev_type().unwrap_or(0) {
        t if t & CL_DEVICE_TYPE_GPU != 0 => "GPU",
        t if t & CL_DEVICE_TYPE_CPU != 0 => "CPU",
        t if t & CL_DEVICE_TYPE_ACCELERATOR != 0 => "accelerator",
        _ => "other",
    };
    let extensions = device.extensions().unwrap_or_default();
    DeviceInfo {
        index,
        platform: platform.to_string(),
        name: device.name().unwrap_or_default().trim().to_string(),
        vendor: device.vendor().unwrap_or_default(),
        kind: kind.to_string(),
        version: device.version().unwrap_or_default(),
        opencl_c_version: device.opencl_c_version().unwrap_or_default(),
        driver_version: device.driver_version().unwrap_or_default(),
        compute_units: device.max_compute_units().unwrap_or(1),
        max_work_group_size: device.max_work_group_size().unwrap_or(1),
        max_mem_alloc_bytes: device.max_mem_alloc_size().unwrap_or(0),
        global_mem_bytes: device.global_mem_size().unwrap_or(0),
        local_mem_bytes: device.local_mem_size().unwrap_or(0),
        fp64: extensions.contains("cl_khr_fp64"),
    }
}

/// All OpenCL devices of all platforms, in the order `--device` indexes them.
pub fn devices() -> Result<Vec<DeviceInfo>, ClError> {
    Ok(discovered()?
        .devices
        .iter()
        .map(|(_, info)| info.clone())
        .collect())
}

/// Which device to use: an explicit index, or the default (the first GPU,
/// else the first device).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub enum DeviceSelection {
    #[default]
    Default,
    Index(usize),
}

impl DeviceSelection {
    /// The selection from a command-line flag, else from `RADIOSITY_CL_DEVICE`,
    /// else the default. A malformed environment value is an error, not
    /// silently ignored.
    pub fn from_flag_or_env(flag: Option<usize>) -> Result<Self, ClError> {
        Self::from_flag_or_value(flag, std::env::var(DEVICE_ENV).ok().as_deref())
    }

    /// [`Self::from_flag_or_env`] with the environment value passed in.
    pub fn from_flag_or_value(flag: Option<usize>, env: Option<&str>) -> Result<Self, ClError> {
        if let Some(index) = flag {
            return Ok(Self::Index(index));
        }
        match env.map(str::trim) {
            None | Some("") => Ok(Self::Default),
            Some(value) => {
                value
                    .parse::<usize>()
                    .map(Self::Index)
                    .map_err(|_| ClError::BadSelection {
                        value: value.to_string(),
                        origin: format!("environment variable {DEVICE_ENV}"),
                    })
            }
        }
    }
}

/// Seconds a command took on the device, from its profiling event.
pub fn event_seconds(event: &Event) -> Result<f64, ClError> {
    let start = event
        .profiling_command_start()
        .map_err(|e| api("reading profiling start", e))?;
    let end = event
        .profiling_command_end()
        .map_err(|e| api("reading profiling end", e))?;
    Ok(end.saturating_sub(start) as f64 * 1e-9)
}

/// An OpenCL call's failure, naming what was being done.
pub fn api(what: &str, e: impl std::fmt::Display) -> ClError {
    ClError::Api {
        what: what.to_string(),
        code: e.to_string(),
    }
}

/// Buffer access from the kernel's point of view.
#[derive(Clone, Copy, Debug)]
pub enum Access {
    ReadOnly,
    WriteOnly,
    ReadWrite,
}

impl Access {
    fn flags(self) -> cl_mem_flags {
        match self {
            Access::ReadOnly => CL_MEM_READ_ONLY,
            Access::WriteOnly => CL_MEM_WRITE_ONLY,
            Access::ReadWrite => CL_MEM_READ_WRITE,
        }
    }
}

/// One OpenCL device with its context and an in-order profiling queue.
pub struct Gpu {
    info: DeviceInfo,
    context: Context,
    queue: CommandQueue,
}

impl Gpu {
    /// Opens the selected device.
    pub fn new(selection: DeviceSelection) -> Result<Self, ClError> {
        let found = discovered()?;
        let index = match selection {
            DeviceSelection::Index(i) => {
                if i >= found.devices.len() {
                    return Err(ClError::NoSuchDevice {
                        index: i,
                        available: found.devices.len(),
                    });
                }
                i
            }
            DeviceSelection::Default => found
                .devices
                .iter()
                .position(|(_, info)| info.kind == "GPU")
                .unwrap_or(0),
        };
        let (device, info) = &found.devices[index];
        let context = Context::from_device(device).map_err(|e| api("creating a context", e))?;
        // `create_default_with_properties` is the OpenCL 2.0 entry point; a
        // 1.2-only platform needs the older call.
        let queue = if info.version.starts_with("OpenCL 1.") {
            #[allow(deprecated)]
            CommandQueue::create_default(&context, CL_QUEUE_PROFILING_ENABLE)
        } else {
            CommandQueue::create_default_with_properties(&context, CL_QUEUE_PROFILING_ENABLE, 0)
        }
        .map_err(|e| api("creating a command queue", e))?;
        Ok(Self {
            info: info.clone(),
            context,
            queue,
        })
    }

    pub fn info(&self) -> &DeviceInfo {
        &self.info
    }

    pub fn queue(&self) -> &CommandQueue {
        &self.queue
    }

    /// Builds an embedded program; a failure carries the compiler's log.
    /// `name` is the kernel file's name, for the message.
    pub fn build(&self, name: &str, source: &str, options: &str) -> Result<Program, ClError> {
        let options = format!("-cl-std=CL1.2 {options}");
        Program::create_and_build_from_source(&self.context, source, &options).map_err(|log| {
            ClError::Build {
                name: name.to_string(),
                device: self.info.name.clone(),
                log,
            }
        })
    }

    /// A kernel from a built program.
    pub fn kernel(&self, program: &Program, name: &str) -> Result<Kernel, ClError> {
        Kernel::create(program, name).map_err(|e| api(&format!("creating kernel {name}"), e))
    }

    /// Checks that one buffer of `bytes` fits the device's single-allocation
    /// limit (`CL_DEVICE_MAX_MEM_ALLOC_SIZE`).
    pub fn check_alloc(&self, name: &str, bytes: u64) -> Result<(), ClError> {
        if bytes > self.info.max_mem_alloc_bytes {
            return Err(ClError::TooLarge {
                name: name.to_string(),
                bytes,
                device: self.info.name.clone(),
                limit_name: "CL_DEVICE_MAX_MEM_ALLOC_SIZE",
                limit: self.info.max_mem_alloc_bytes,
            });
        }
        Ok(())
    }

    /// Checks that a stage's buffers together fit in global memory.
    pub fn check_total(&self, stage: &str, bytes: u64) -> Result<(), ClError> {
        if bytes > self.info.global_mem_bytes {
            return Err(ClError::TooLarge {
                name: format!("all buffers of {stage}"),
                bytes,
                device: self.info.name.clone(),
                limit_name: "CL_DEVICE_GLOBAL_MEM_SIZE",
                limit: self.info.global_mem_bytes,
            });
        }
        Ok(())
    }

    /// A device buffer of `len` elements (at least one: OpenCL forbids empty
    /// buffers), checked against the device's limits.
    pub fn buffer<T>(&self, name: &str, len: usize, access: Access) -> Result<Buffer<T>, ClError> {
        let bytes = (len.max(1) as u64).saturating_mul(std::mem::size_of::<T>() as u64);
        self.check_alloc(name, bytes)?;
        // SAFETY: no host pointer is passed; the buffer is uninitialised
        // device memory that kernels or writes fill before it is read.
        unsafe {
            Buffer::<T>::create(
                &self.context,
                access.flags(),
                len.max(1),
                std::ptr::null_mut(),
            )
        }
        .map_err(|e| api(&format!("allocating buffer {name} ({bytes} bytes)"), e))
    }

    /// A device buffer holding a copy of `data`.
    pub fn upload<T>(&self, name: &str, data: &[T], access: Access) -> Result<Buffer<T>, ClError> {
        let mut buffer = self.buffer::<T>(name, data.len(), access)?;
        if !data.is_empty() {
            // SAFETY: blocking write of exactly `data.len()` elements into a
            // buffer of at least that many.
            unsafe {
                self.queue
                    .enqueue_write_buffer(&mut buffer, CL_BLOCKING, 0, data, &[])
                    .map_err(|e| api(&format!("writing buffer {name}"), e))?;
            }
        }
        Ok(buffer)
    }

    /// Reads the first `len` elements of a buffer back to the host.
    pub fn download<T: Default + Clone>(
        &self,
        name: &str,
        buffer: &Buffer<T>,
        len: usize,
    ) -> Result<Vec<T>, ClError> {
        let mut out = vec![T::default(); len];
        if len > 0 {
            // SAFETY: blocking read of `len` elements from a buffer created
            // with at least `len` elements.
            unsafe {
                self.queue
                    .enqueue_read_buffer(buffer, CL_BLOCKING, 0, &mut out, &[])
                    .map_err(|e| api(&format!("reading buffer {name}"), e))?;
            }
        }
        Ok(out)
    }

    /// Waits for all queued work.
    pub fn finish(&self) -> Result<(), ClError> {
        self.queue.finish().map_err(|e| api("clFinish", e))
    }

    /// The 1-D local size for `kernel`: `preferred`, bounded by what the
    /// kernel and device allow. Always an explicit size, since PoCL compiles
    /// a kernel anew for every distinct local size (TOOLCHAIN.md).
    pub fn local_size(&self, kernel: &Kernel, preferred: usize) -> usize {
        let ids = self.context.devices();
        let kernel_max = ids
            .first()
            .and_then(|&id| kernel.get_work_group_size(id).ok())
            .unwrap_or(1);
        preferred
            .min(kernel_max)
            .min(self.info.max_work_group_size)
            .max(1)
    }

    /// Runs a configured kernel launch and returns its device time in
    /// seconds. `launch` enqueues the kernel and returns its event.
    pub fn timed(
        &self,
        what: &str,
        launch: impl FnOnce() -> opencl3::Result<Event>,
    ) -> Result<f64, ClError> {
        let event = launch().map_err(|e| api(what, e))?;
        event.wait().map_err(|e| api(what, e))?;
        event_seconds(&event)
    }
}

/// `n` rounded up to a multiple of `local` (global sizes must be multiples of
/// the local size in OpenCL 1.2; kernels guard with the real `n`).
pub fn round_up(n: usize, local: usize) -> usize {
    n.div_ceil(local).max(1) * local
}

/// Where a stage runs: the f64 CPU reference, or an OpenCL device.
pub enum Backend<'a> {
    /// The CPU reference implementation (rayon, f64).
    Cpu,
    /// An OpenCL device.
    OpenCl(&'a Gpu),
}

impl Backend<'_> {
    /// A copy of the selection (`Backend` borrows the device; this is not
    /// `Copy` only because it need not be).
    pub fn reborrow(&self) -> Backend<'_> {
        match self {
            Backend::Cpu => Backend::Cpu,
            Backend::OpenCl(g) => Backend::OpenCl(g),
        }
    }

    /// The device's name for reports.
    pub fn device_name(&self) -> String {
        match self {
            Backend::OpenCl(g) => format!(
                "{} ({}, {})",
                g.info().name,
                g.info().kind,
                g.info().platform
            ),
            Backend::Cpu => "CPU reference (f64)".to_string(),
        }
    }
}
