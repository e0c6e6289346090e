//! Reading a frame back to the host: one mappable buffer, made when the frame's size is set and
//! reused for every frame.

use std::sync::mpsc;

use crate::context::GpuContext;
use crate::error::GpuError;

/// A host-mappable copy target of `size` bytes.
pub(crate) struct Readback {
    pub(crate) buffer: wgpu::Buffer,
    size: u64,
}

impl Readback {
    pub(crate) fn new(ctx: &GpuContext, size: u64) -> Readback {
        let buffer = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("prt-gpu readback"),
            size: size.max(4),
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        Readback { buffer, size }
    }

    /// Its size in bytes.
    pub(crate) fn size(&self) -> u64 {
        self.size
    }

    /// Maps the buffer once the submitted copy into it is done and hands its bytes to `read`.
    pub(crate) fn read<T>(
        &self,
        ctx: &GpuContext,
        read: impl FnOnce(&[u8]) -> T,
    ) -> Result<T, GpuError> {
        let slice = self.buffer.slice(..self.size.max(4));
        let (tx, rx) = mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            // The receiver waits below; a send can only fail if it is gone.
            let _ = tx.send(r);
        });
        ctx.wait("reading a frame back")?;
        let mapped = rx.recv().map_err(|e| GpuError::Backend {
            during: "reading a frame back",
            reason: e.to_string(),
        })?;
        mapped.map_err(|e| GpuError::Backend {
            during: "reading a frame back",
            reason: e.to_string(),
        })?;
        let out = {
            let view = slice.get_mapped_range().map_err(|e| GpuError::Backend {
                during: "reading a frame back",
                reason: e.to_string(),
            })?;
            read(&view[..self.size as usize])
        };
        self.buffer.unmap();
        Ok(out)
    }
}
