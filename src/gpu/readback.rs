//! Copying GPU buffers back to the CPU (once per stage, never per shot).

use anyhow::{Result, anyhow};

use super::Gpu;

/// Reads the first `count` elements of `buffer` (which needs COPY_SRC).
pub fn read_buffer<T: bytemuck::Pod>(gpu: &Gpu, buffer: &wgpu::Buffer, count: usize) -> Result<Vec<T>> {
    let size = (count * std::mem::size_of::<T>()) as u64;
    if size == 0 {
        return Ok(Vec::new());
    }
    let staging = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("readback"),
        size,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    encoder.copy_buffer_to_buffer(buffer, 0, &staging, 0, size);
    gpu.queue.submit([encoder.finish()]);

    let (sender, receiver) = std::sync::mpsc::channel();
    staging.slice(..).map_async(wgpu::MapMode::Read, move |result| {
        let _ = sender.send(result);
    });
    gpu.wait()?;
    // A completed wait has run every callback of the work it waited for:
    // nothing here means the mapping was dropped, and blocking would hang.
    receiver
        .try_recv()
        .map_err(|_| anyhow!("GPU read-back was abandoned"))?
        .map_err(|e| anyhow!("GPU read-back failed: {e}"))?;
    let data = staging.slice(..).get_mapped_range().map_err(|e| anyhow!("GPU read-back failed: {e:?}"))?;
    let values = bytemuck::cast_slice::<u8, T>(&data).to_vec();
    drop(data);
    staging.unmap();
    Ok(values)
}

/// Reads the elements at `indices` of `buffer` (which needs COPY_SRC): one
/// small copy each, for a few probe values per batch. Element size must be a
/// multiple of 4 bytes.
pub fn read_elements<T: bytemuck::Pod>(gpu: &Gpu, buffer: &wgpu::Buffer, indices: &[u32]) -> Result<Vec<T>> {
    let size = std::mem::size_of::<T>() as u64;
    if indices.is_empty() {
        return Ok(Vec::new());
    }
    let gathered = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("readback gathered"),
        size: size * indices.len() as u64,
        usage: wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut encoder = gpu.device.create_command_encoder(&Default::default());
    for (k, &i) in indices.iter().enumerate() {
        encoder.copy_buffer_to_buffer(buffer, i as u64 * size, &gathered, k as u64 * size, size);
    }
    gpu.queue.submit([encoder.finish()]);
    read_buffer(gpu, &gathered, indices.len())
}
