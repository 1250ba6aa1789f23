//! Copying GPU buffers back to the CPU (once per stage, never per shot).

use anyhow::{Result, anyhow};

use super::Gpu;

/// How long a read-back waits for its mapping's callback once the GPU work
/// is done: a thread sharing the device may be running it.
const CALLBACK_GRACE: std::time::Duration = std::time::Duration::from_secs(5);

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
    // A completed wait has run this mapping's callback, or another thread
    // polling the same device has taken it and is about to run it. A dropped
    // mapping drops the sender, so this waits only on that other thread.
    receiver
        .recv_timeout(CALLBACK_GRACE)
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

#[cfg(test)]
mod tests {
    use wgpu::util::DeviceExt;

    use super::*;

    /// Two threads reading back through one device: each one's wait may be
    /// the poll that runs the other's mapping callback.
    #[test]
    fn threads_sharing_a_device_each_read_back_their_own_buffer() {
        let gpu = Gpu::new(None).expect("an adapter");
        std::thread::scope(|scope| {
            for seed in [1u32, 2] {
                let gpu = &gpu;
                scope.spawn(move || {
                    let values: Vec<u32> = (0..256).map(|i| i * seed).collect();
                    let buffer = gpu.device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                        label: None,
                        contents: bytemuck::cast_slice(&values),
                        usage: wgpu::BufferUsages::COPY_SRC,
                    });
                    for _ in 0..1000 {
                        assert_eq!(read_buffer::<u32>(gpu, &buffer, values.len()).unwrap(), values);
                    }
                });
            }
        });
    }
}
