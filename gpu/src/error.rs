//! Every refusal of the GPU backend, naming what is wrong.

use prt_runtime::RuntimeError;

/// Why the GPU backend could not open, upload or render.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum GpuError {
    /// No adapter (GPU or software driver) was found for the backends tried.
    #[error(
        "no GPU adapter found ({reason}); on a machine without a GPU install a software Vulkan \
         driver (Debian: mesa-vulkan-drivers libvulkan1) or render on the CPU (relight without --gpu)"
    )]
    NoAdapter {
        /// What wgpu said.
        reason: String,
    },
    /// The adapter refused to create a device.
    #[error("the GPU adapter {adapter} could not create a device: {reason}")]
    Device {
        /// The adapter's name.
        adapter: String,
        /// What wgpu said.
        reason: String,
    },
    /// The bake needs more than a device limit allows.
    #[error("{what} needs {needed} but the device's {limit} is {max}")]
    Limit {
        /// The wgpu limit's name (`max_storage_buffer_binding_size`, ...).
        limit: &'static str,
        /// What needs it.
        what: String,
        /// What it needs.
        needed: u64,
        /// The device's limit.
        max: u64,
    },
    /// The device reported an error while uploading or rendering (out of memory, a lost
    /// device, a failed read-back).
    #[error("GPU error while {during}: {reason}")]
    Backend {
        /// What was being done.
        during: &'static str,
        /// What the device said.
        reason: String,
    },
    /// The bake holds something this backend does not render.
    #[error("the GPU backend cannot render this bake: {0}")]
    Unsupported(String),
    /// The bake file could not be read.
    #[error(transparent)]
    Format(#[from] prt_formats::FormatError),
    /// A refusal of the CPU runtime (a bad buffer length, camera, environment, material).
    #[error(transparent)]
    Runtime(#[from] RuntimeError),
}
