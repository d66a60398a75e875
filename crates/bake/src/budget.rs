//! Memory budgets, checked before the bake allocates: what the stages will
//! need for `n` patches against what the machine and the device have, and
//! the bake file's format limit. A request that does not fit is refused
//! with how much it needs, how much there is and the largest patch count
//! that fits — before the time of voxelizing or tracing is spent, and
//! before anything is written.
//!
//! **What a bake holds** (bytes, dominant terms). The form factors run
//! over all `N` of the voxelization's patches; the patches that see no
//! other surface (Sponza's roofs and outer walls: about 30 % of them) are
//! removed there, and every later matrix is `n × n` over the `n` kept:
//! - form factors by rays: the counts (f32, `4N²`) and the symmetrised
//!   `A F` (f64, `8N²`), then `F` (f32, `4n²`): `16N²` at the most
//!   ([`check_form_factors`]);
//! - transfer and after ([`check`]): `F` (kept for the export, `4n²`), `T` (3 channels
//!   of f32, `12n²`), their reordered copies for the encoder (`12n²`), and
//!   during the LU solve its host copy of `I − diag(ρ) F` (`4n²`): `32n²`;
//! - on the OpenCL device, the transfer's padded matrices: two for the LU
//!   solve, three for doubling (five with Horner steps); on a CPU device
//!   (PoCL) these live in the same RAM and are added to the host's share.
//!   Each is one buffer, so it must also fit the device's single-allocation
//!   limit (`CL_DEVICE_MAX_MEM_ALLOC_SIZE`, a quarter of the memory on
//!   many drivers); the ray kernel's BVH and batch (`crate::trace`, tens
//!   of MB) are freed before the transfer starts (`docs/memory.md`);
//! - the CPU f64 reference: faer's f64 matrices (`M`, its LU, `F` and `T`,
//!   `32n²`) on top of the above;
//! - inspection exports: the decoded matrix and its reordered copy
//!   (`24n²`) on top.
//!
//! The bake file addresses `n²` matrix entries with 32-bit indices
//! ([`crate::encode`]): `n ≤ 65,535`.

use crate::compute::DeviceInfo;
use crate::error::BakeError;

/// The stage name in errors.
pub const STAGE: &str = "memory budget";

/// Host bytes per `N²` of the form factors over all `N` of the
/// voxelization's patches (module doc): the rays' counts and the
/// symmetrised `A F` at the peak, with room for `F`.
const FORM_FACTORS_PER_ENTRY: u64 = 16;
/// Host bytes per `n²` of the stages after the form factors (module doc).
const HOST_PER_ENTRY: u64 = 32;
/// Extra host bytes per `n²` of the CPU f64 reference.
const CPU_REFERENCE_PER_ENTRY: u64 = 32;
/// Extra host bytes per `n²` of the inspection exports.
const EXPORT_PER_ENTRY: u64 = 24;
/// Rows and columns a device matrix is padded to a multiple of: the
/// largest GEMM tile ([`crate::gemm::GemmConfig`]).
const PAD: u64 = 256;

/// The largest `n` whose `n²` fits the codec's 32-bit entry indices.
pub const MAX_PATCHES_FORMAT: usize = 65_535;

/// Where the transfer stage runs, for its share of memory.
#[derive(Clone, Copy, Debug)]
pub enum Device<'a> {
    /// The f64 CPU reference.
    CpuReference,
    /// An OpenCL device; `matrices` padded `n × n` f32 buffers on it.
    OpenCl { info: &'a DeviceInfo, matrices: u64 },
}

/// What `n` patches need, in bytes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Needs {
    pub host: u64,
    pub device: u64,
}

/// The bytes `n` patches need on the host and on the device (`export`:
/// with the inspection exports).
pub fn needs(n: usize, device: Device, export: bool) -> Needs {
    let nn = (n as u64).saturating_mul(n as u64);
    let per = HOST_PER_ENTRY + if export { EXPORT_PER_ENTRY } else { 0 };
    let mut host = per.saturating_mul(nn);
    let mut dev = 0;
    match device {
        Device::CpuReference => host = host.saturating_add(CPU_REFERENCE_PER_ENTRY * nn),
        Device::OpenCl { info, matrices } => {
            dev = (4 * matrices).saturating_mul(nn);
            if info.kind == "CPU" {
                host = host.saturating_add(dev);
            }
        }
    }
    Needs { host, device: dev }
}

/// The largest `n` with `needs(n)` within `host` and `device` bytes.
pub fn largest_fitting(host: u64, device: Device, export: bool) -> usize {
    let per = needs(1, device, export);
    let mut n = ((host / per.host.max(1)) as f64).sqrt() as usize;
    if let Device::OpenCl { info, .. } = device {
        if per.device > 0 && info.kind != "CPU" {
            n = n.min(((info.global_mem_bytes / per.device) as f64).sqrt() as usize);
        }
        n = n.min(largest_single(info));
    }
    n.min(MAX_PATCHES_FORMAT)
}

/// The largest `n` whose padded `n × n` f32 matrix fits one device buffer.
fn largest_single(info: &DeviceInfo) -> usize {
    let side = ((info.max_mem_alloc_bytes / 4) as f64).sqrt() as u64;
    (side / PAD * PAD) as usize
}

/// Bytes of one padded `n × n` f32 device matrix.
fn matrix_bytes(n: usize) -> u64 {
    let p = (n as u64).div_ceil(PAD) * PAD;
    4 * p * p
}

/// The host memory available for new allocations: `MemAvailable` of
/// `/proc/meminfo` (Linux), or `None` where it cannot be read.
pub fn host_available() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib.saturating_mul(1024))
}

/// Gigabytes, for messages.
fn gb(bytes: u64) -> String {
    format!("{:.1} GB", bytes as f64 / 1e9)
}

/// Checks that the form factors of all `n_all` voxel patches fit the
/// host's `available` bytes (`None`: unknown, not checked); the stages
/// after them are checked on the patches they keep ([`check`]).
pub fn check_form_factors(n_all: usize, available: Option<u64>) -> Result<(), BakeError> {
    let need = FORM_FACTORS_PER_ENTRY.saturating_mul((n_all as u64).saturating_mul(n_all as u64));
    match available {
        Some(avail) if need > avail => Err(BakeError::TooLarge {
            stage: STAGE,
            detail: format!(
                "the voxelization has {n_all} patches: their form factors need about {} of \
                 memory ({n_all} × {n_all} counts and sums), this machine has {} available; at \
                 most about {} voxel patches fit",
                gb(need),
                gb(avail),
                ((avail / FORM_FACTORS_PER_ENTRY) as f64).sqrt() as u64
            ),
        }),
        _ => Ok(()),
    }
}

/// Checks that a bake of `n` patches fits: the format limit, the host's
/// `available` bytes (`None`: unknown, not checked) and the device's
/// global memory. `what` says where `n` comes from ("the requested patch
/// count", "the voxelization's patches"); `export`: with the inspection
/// exports.
pub fn check(
    n: usize,
    what: &str,
    available: Option<u64>,
    device: Device,
    export: bool,
) -> Result<(), BakeError> {
    if n > MAX_PATCHES_FORMAT {
        return Err(BakeError::TooLarge {
            stage: STAGE,
            detail: format!(
                "{what} is {n}: the bake file indexes the n² matrix entries with 32 bits, so \
                 at most {MAX_PATCHES_FORMAT} patches fit"
            ),
        });
    }
    let need = needs(n, device, export);
    if let Some(avail) = available {
        if need.host > avail {
            return Err(BakeError::TooLarge {
                stage: STAGE,
                detail: format!(
                    "{what} is {n}: the bake needs about {} of memory (form factors, transfer \
                     and codec matrices of {n} × {n}), this machine has {} available; at most \
                     about {} patches fit",
                    gb(need.host),
                    gb(avail),
                    largest_fitting(avail, device, export)
                ),
            });
        }
    }
    if let Device::OpenCl { info, matrices } = device {
        if matrices > 0 && matrix_bytes(n) > info.max_mem_alloc_bytes {
            return Err(BakeError::TooLarge {
                stage: STAGE,
                detail: format!(
                    "{what} is {n}: one transfer matrix of {n} × {n} takes {} on the OpenCL \
                     device {}, whose largest buffer (CL_DEVICE_MAX_MEM_ALLOC_SIZE) is {}; at \
                     most about {} patches fit",
                    gb(matrix_bytes(n)),
                    info.name,
                    gb(info.max_mem_alloc_bytes),
                    largest_single(info).min(MAX_PATCHES_FORMAT)
                ),
            });
        }
        if info.kind != "CPU" && need.device > info.global_mem_bytes {
            return Err(BakeError::TooLarge {
                stage: STAGE,
                detail: format!(
                    "{what} is {n}: the transfer stage needs about {} on the OpenCL device {}, \
                     which has {}; at most about {} patches fit",
                    gb(need.device),
                    info.name,
                    gb(info.global_mem_bytes),
                    largest_fitting(available.unwrap_or(u64::MAX), device, export)
                ),
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gpu(global: u64, single: u64) -> DeviceInfo {
        DeviceInfo {
            index: 0,
            platform: "test".into(),
            name: "a GPU".into(),
            vendor: "test".into(),
            kind: "GPU".into(),
            version: "OpenCL 3.0".into(),
            opencl_c_version: "OpenCL C 1.2".into(),
            driver_version: "1".into(),
            compute_units: 1,
            max_work_group_size: 1024,
            max_mem_alloc_bytes: single,
            global_mem_bytes: global,
            local_mem_bytes: 48 << 10,
            fp64: true,
        }
    }

    /// A transfer matrix larger than the device's largest buffer is
    /// refused before the bake, naming the limit and the largest count
    /// that fits; that count passes.
    #[test]
    fn one_matrix_must_fit_the_single_allocation_limit() {
        let info = gpu(100_000_000_000, 1_000_000_000);
        let device = Device::OpenCl {
            info: &info,
            matrices: 2,
        };
        let e = check(20_000, "the requested patch count", None, device, false)
            .unwrap_err()
            .to_string();
        assert!(e.contains("CL_DEVICE_MAX_MEM_ALLOC_SIZE"), "{e}");
        // 1e9 / 4 floats: a side of 15,811, whole tiles of 256: 15,616.
        assert!(e.contains("at most about 15616 patches"), "{e}");
        assert!(check(15_616, "n", None, device, false).is_ok());
        assert!(check(15_617, "n", None, device, false).is_err());
        assert_eq!(largest_fitting(u64::MAX, device, false), 15_616);
    }

    /// The form factors are checked on all of the voxelization's patches
    /// at 16 bytes per pair, the later stages on the kept ones: Sponza at
    /// `--patches 20000` (29,202 voxel patches, about 20,000 kept) fits
    /// 24.6 GB, which counting every voxel patch at the later stages'
    /// rate (34.1 GB) refused.
    #[test]
    fn the_form_factors_count_every_voxel_patch_the_rest_the_kept_ones() {
        let avail = Some(24_600_000_000);
        assert!(check_form_factors(29_202, avail).is_ok());
        assert!(check(20_000, "n", avail, Device::CpuReference, false).is_err());
        let pocl = DeviceInfo {
            kind: "CPU".into(),
            ..gpu(24_000_000_000, 24_000_000_000)
        };
        let device = Device::OpenCl {
            info: &pocl,
            matrices: 2,
        };
        // 40 bytes per pair with the PoCL device's two matrices in host RAM.
        assert!(check(20_000, "n", avail, device, false).is_ok());
        assert!(check(29_202, "n", avail, device, false).is_err());
        let e = check_form_factors(40_000, avail).unwrap_err().to_string();
        assert!(e.contains("40000 patches") && e.contains("25.6 GB"), "{e}");
        // ⌊√(24.6e9 / 16)⌋ = 39,210.
        assert!(e.contains("at most about 39210 voxel patches"), "{e}");
        assert!(check_form_factors(39_210, avail).is_ok());
        assert!(check_form_factors(39_211, avail).is_err());
    }

    /// The H200 of issue 41 (141 GB, a quarter of it in one buffer) fits
    /// Sponza at 32,000 patches with the LU solve's two matrices, and the
    /// host's 128 GB do too.
    #[test]
    fn thirty_two_thousand_patches_fit_an_h200() {
        let info = gpu(150_000_000_000, 37_500_000_000);
        let device = Device::OpenCl {
            info: &info,
            matrices: 2,
        };
        assert!(check(32_000, "n", Some(128_000_000_000), device, false).is_ok());
        let need = needs(32_000, device, false);
        assert_eq!(need.device, 8 * 32_000 * 32_000);
        assert_eq!(need.host, 32 * 32_000 * 32_000);
    }
}
