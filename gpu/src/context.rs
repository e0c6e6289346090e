//! The device a relighter renders on: adapter choice, the limits asked for, and turning the
//! device's asynchronous errors into [`GpuError`]s.

use std::future::Future;

use crate::error::GpuError;

/// How to choose the device.
#[derive(Clone, Debug, Default)]
pub struct GpuOptions {
    /// Take the software fallback adapter (lavapipe under Vulkan) even when a GPU is present:
    /// wgpu's `force_fallback_adapter`.
    pub fallback: bool,
    /// Bind at most this many bytes of one tensor per storage binding, below the device's
    /// own `max_storage_buffer_binding_size` (the tests use it to split tiny bakes across
    /// bindings the way a large bake is split on any device).
    pub max_binding_bytes: Option<u64>,
    /// Per-vertex: run the light and material stages' per-vertex work on the CPU and upload
    /// their records, as a bake over a device limit does (the benchmark compares the two; the
    /// tests keep that path checked).
    pub vertex_stages_on_cpu: bool,
}

/// A device and its queue, shared by the relighters made on it (wgpu's handles are
/// reference-counted, so a relighter keeps clones).
#[derive(Clone, Debug)]
pub struct GpuContext {
    pub(crate) device: wgpu::Device,
    pub(crate) queue: wgpu::Queue,
    info: wgpu::AdapterInfo,
    limits: wgpu::Limits,
    max_binding_bytes: u64,
    vertex_stages_on_cpu: bool,
}

impl GpuContext {
    /// Finds an adapter (the high-performance one, or the fallback with
    /// [`GpuOptions::fallback`]; wgpu's `WGPU_BACKEND` and `WGPU_ADAPTER_NAME` variables are
    /// honoured) and creates a device with the adapter's own limits, so that large tensors
    /// fit where the hardware allows. [`GpuError::NoAdapter`] when there is none.
    pub fn new(options: &GpuOptions) -> Result<GpuContext, GpuError> {
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let adapter = match block_on(wgpu::util::initialize_adapter_from_env(&instance, None)) {
            Ok(a) if !options.fallback => a,
            _ => block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
                power_preference: wgpu::PowerPreference::HighPerformance,
                force_fallback_adapter: options.fallback,
                compatible_surface: None,
                apply_limit_buckets: false,
            }))
            .map_err(|e| GpuError::NoAdapter {
                reason: e.to_string(),
            })?,
        };
        let info = adapter.get_info();
        let limits = adapter.limits();
        let (device, queue) = block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("prt-gpu"),
            required_features: wgpu::Features::empty(),
            required_limits: limits.clone(),
            experimental_features: wgpu::ExperimentalFeatures::disabled(),
            memory_hints: wgpu::MemoryHints::Performance,
            trace: wgpu::Trace::Off,
        }))
        .map_err(|e| GpuError::Device {
            adapter: info.name.clone(),
            reason: e.to_string(),
        })?;
        let device_max = limits
            .max_storage_buffer_binding_size
            .min(limits.max_buffer_size);
        let max_binding_bytes = options
            .max_binding_bytes
            .map_or(device_max, |m| m.min(device_max));
        Ok(GpuContext {
            device,
            queue,
            info,
            limits,
            max_binding_bytes,
            vertex_stages_on_cpu: options.vertex_stages_on_cpu,
        })
    }

    /// The adapter's name, backend and driver, e.g. `"NVIDIA H200 (Vulkan, 550.54)"`.
    pub fn adapter_name(&self) -> String {
        let i = &self.info;
        let driver = [i.driver.as_str(), i.driver_info.as_str()]
            .iter()
            .filter(|s| !s.is_empty())
            .copied()
            .collect::<Vec<_>>()
            .join(" ");
        format!(
            "{} ({:?}, {:?}, {driver})",
            i.name, i.backend, i.device_type
        )
    }

    /// Whether the adapter is a software renderer (lavapipe, WARP) rather than a GPU.
    pub fn is_software(&self) -> bool {
        self.info.device_type == wgpu::DeviceType::Cpu
    }

    /// The device's limits (the adapter's own).
    pub fn limits(&self) -> &wgpu::Limits {
        &self.limits
    }

    /// The device, for callers that render into their own textures.
    pub fn device(&self) -> &wgpu::Device {
        &self.device
    }

    /// The queue.
    pub fn queue(&self) -> &wgpu::Queue {
        &self.queue
    }

    /// Bytes of bake data (stored tensors, vertex records and tables) one storage binding
    /// may hold: the device's limit, or [`GpuOptions::max_binding_bytes`] below it.
    pub(crate) fn max_binding_bytes(&self) -> u64 {
        self.max_binding_bytes
    }

    /// [`GpuOptions::vertex_stages_on_cpu`].
    pub(crate) fn vertex_stages_on_cpu(&self) -> bool {
        self.vertex_stages_on_cpu
    }

    /// Bytes one storage binding may hold on the device (for the frame's own buffers).
    pub(crate) fn device_binding_bytes(&self) -> u64 {
        self.limits
            .max_storage_buffer_binding_size
            .min(self.limits.max_buffer_size)
    }

    /// Runs `f` (resource creation or uploads) and reports a validation or out-of-memory error
    /// the device raised meanwhile as [`GpuError::Backend`] instead of wgpu's default panic.
    pub(crate) fn checked<T>(
        &self,
        during: &'static str,
        f: impl FnOnce() -> Result<T, GpuError>,
    ) -> Result<T, GpuError> {
        let oom = self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let validation = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let out = f();
        let v = block_on(validation.pop());
        let o = block_on(oom.pop());
        if let Some(e) = v.or(o) {
            return Err(GpuError::Backend {
                during,
                reason: e.to_string(),
            });
        }
        out
    }

    /// Waits for the queue's work to finish.
    pub(crate) fn wait(&self, during: &'static str) -> Result<(), GpuError> {
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map(|_| ())
            .map_err(|e| GpuError::Backend {
                during,
                reason: e.to_string(),
            })
    }
}

/// Drives one of wgpu's futures to completion (native wgpu resolves them on `poll`).
pub(crate) fn block_on<F: Future>(f: F) -> F::Output {
    pollster::block_on(f)
}
