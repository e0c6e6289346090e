//! Device buffers made from host bytes, and the check every storage binding passes (the
//! device's `max_storage_buffer_binding_size`, or `GpuOptions::max_binding_bytes` below it).

use crate::context::GpuContext;
use crate::error::GpuError;

/// A device buffer holding `bytes` (padded with zeros to whole words).
pub(crate) fn upload(
    ctx: &GpuContext,
    label: &str,
    bytes: &[u8],
    usage: wgpu::BufferUsages,
) -> Result<wgpu::Buffer, GpuError> {
    let size = (bytes.len() as u64).div_ceil(4).max(1) * 4;
    let buffer = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size,
        usage,
        mapped_at_creation: true,
    });
    {
        let mut view = buffer
            .slice(..)
            .get_mapped_range_mut()
            .map_err(|e| GpuError::Backend {
                during: "uploading",
                reason: e.to_string(),
            })?;
        view.slice(..bytes.len()).copy_from_slice(bytes);
    }
    buffer.unmap();
    Ok(buffer)
}

/// Refuses a buffer larger than one storage binding.
pub(crate) fn check_binding(ctx: &GpuContext, what: &str, bytes: u64) -> Result<(), GpuError> {
    let max = ctx.max_binding_bytes();
    if bytes > max {
        return Err(GpuError::Limit {
            limit: "max_storage_buffer_binding_size",
            what: what.to_string(),
            needed: bytes,
            max,
        });
    }
    Ok(())
}

pub(crate) fn storage_buffer(
    ctx: &GpuContext,
    label: &str,
    bytes: &[u8],
) -> Result<wgpu::Buffer, GpuError> {
    check_binding(ctx, label, bytes.len() as u64)?;
    upload(
        ctx,
        label,
        bytes,
        wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
    )
}
