//! The GPU handle every stage receives: device, queue, the adapter that was
//! chosen, the one list of shaders, and read-back.
//!
//! Stages never create a `Gpu`; `main` (or a test) makes one and passes it
//! down, as wgpu's `hello_compute` example separates set-up from work.

mod built;
#[cfg(test)]
mod form_factors;
mod materials;
#[cfg(test)]
pub(crate) mod mirror;
mod readback;
mod shaders;

pub use materials::Materials;
pub use readback::{read_buffer, read_elements};
pub use shaders::Shader;

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use anyhow::{Context, Result, bail};
use serde::{Deserialize, Serialize};

/// What the report and the terminal say about the adapter that ran the bake.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct AdapterDescription {
    pub name: String,
    /// "Vulkan", "Metal", "Dx12", ...
    pub backend: String,
    /// "DiscreteGpu", "IntegratedGpu", "Cpu", ...
    pub device_type: String,
    pub driver: String,
}

impl AdapterDescription {
    /// Whether the adapter is a CPU driver (lavapipe, WARP).
    pub fn is_cpu(&self) -> bool {
        self.device_type == format!("{:?}", wgpu::DeviceType::Cpu)
    }
}

impl std::fmt::Display for AdapterDescription {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} ({}, {}", self.name, self.backend, self.device_type)?;
        if !self.driver.is_empty() {
            write!(f, ", {}", self.driver)?;
        }
        write!(f, ")")
    }
}

/// Device, queue and adapter facts, shared by all stages.
pub struct Gpu {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub adapter: AdapterDescription,
    pub limits: wgpu::Limits,
    /// Validation, out-of-memory and device-lost messages not yet reported.
    errors: Arc<Mutex<Vec<String>>>,
    /// Why the device was lost, once it is: every later GPU call fails.
    lost: Arc<Mutex<Option<String>>>,
    /// The stage whose first wait destroys the device (`BAKE_TEST_LOSE_DEVICE`).
    lose_at: Option<String>,
    /// The stage running now, for the test hook.
    stage: Mutex<String>,
    /// Largest allocator total seen by `wait` since `take_memory_peak` (bytes).
    memory_peak: AtomicU64,
    /// Longest a `wait` blocks before the GPU counts as hung (`None`: forever).
    wait_timeout: Option<Duration>,
    /// Shader modules, layouts and pipelines already built.
    built: built::Built,
}

/// Environment variable of the device-loss test hook (see `Gpu::wait`).
pub const LOSE_DEVICE_HOOK: &str = "BAKE_TEST_LOSE_DEVICE";

/// Features every bake needs. FLOAT32_BLENDABLE: texelization sums each
/// texel's exact covered area with additive blending into an R32Float target.
const REQUIRED_FEATURES: wgpu::Features = wgpu::Features::FLOAT32_BLENDABLE;

const NO_ADAPTER_HELP: &str = "no GPU adapter found: install a Vulkan driver; without a GPU, \
     Mesa's CPU driver works: `sudo apt-get install mesa-vulkan-drivers libvulkan1`";

impl Gpu {
    /// Opens the best adapter, or the first whose name contains `wanted`
    /// (case-insensitive). Prefers a discrete GPU, then integrated, then a
    /// CPU driver such as Mesa's lavapipe.
    pub fn new(wanted: Option<&str>) -> Result<Gpu> {
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
            backends: wgpu::Backends::PRIMARY,
            ..wgpu::InstanceDescriptor::new_without_display_handle()
        });
        let adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::PRIMARY));
        if adapters.is_empty() {
            bail!(NO_ADAPTER_HELP);
        }
        let adapter = match wanted {
            Some(wanted) => {
                let needle = wanted.to_lowercase();
                let names: Vec<String> = adapters.iter().map(|a| a.get_info().name).collect();
                adapters
                    .into_iter()
                    .find(|a| a.get_info().name.to_lowercase().contains(&needle))
                    .with_context(|| format!("no adapter matches --adapter '{wanted}'; found: {}", names.join(", ")))?
            }
            None => adapters
                .into_iter()
                .min_by_key(|a| preference_rank(a.get_info().device_type))
                .context(NO_ADAPTER_HELP)?,
        };
        let info = adapter.get_info();
        let description = AdapterDescription {
            name: info.name.clone(),
            backend: format!("{:?}", info.backend),
            device_type: format!("{:?}", info.device_type),
            driver: [info.driver.as_str(), info.driver_info.as_str()]
                .iter()
                .filter(|s| !s.is_empty())
                .copied()
                .collect::<Vec<_>>()
                .join(" "),
        };
        let missing = REQUIRED_FEATURES - adapter.features();
        if !missing.is_empty() {
            bail!("adapter {description} lacks required features {missing:?}");
        }
        // Ask for the adapter's own limits: wgpu's defaults are far lower
        // (e.g. 8192² textures, 128 MiB storage bindings are not guaranteed).
        let limits = adapter.limits();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("bake"),
            required_features: REQUIRED_FEATURES,
            required_limits: limits.clone(),
            ..Default::default()
        }))
        .with_context(|| format!("could not open adapter {description}"))?;

        let errors = Arc::new(Mutex::new(Vec::new()));
        let sink = errors.clone();
        device.on_uncaptured_error(Arc::new(move |error: wgpu::Error| {
            let message = match &error {
                wgpu::Error::OutOfMemory { .. } => "GPU out of memory".to_string(),
                other => format!("{other}"),
            };
            sink.lock().unwrap().push(message);
        }));
        // Only the test hook destroys the device (dropping it does not call
        // this), so `Destroyed` is a loss like any other here.
        let lost = Arc::new(Mutex::new(None));
        let sink = lost.clone();
        device.set_device_lost_callback(move |reason, message| {
            let why = match (reason, message.trim()) {
                (wgpu::DeviceLostReason::Destroyed, _) => "destroyed".to_string(),
                (_, "") => format!("{reason:?}"),
                (_, message) => one_line(message),
            };
            sink.lock().unwrap().get_or_insert(why);
        });
        Ok(Gpu {
            device,
            queue,
            adapter: description,
            limits,
            errors,
            lost,
            lose_at: std::env::var(LOSE_DEVICE_HOOK).ok().filter(|s| !s.is_empty()),
            stage: Mutex::new(String::new()),
            memory_peak: AtomicU64::new(0),
            wait_timeout: None,
            built: Default::default(),
        })
    }

    /// Makes every `wait` give up after `timeout`: a driver that stops
    /// answering without reporting a lost device then fails the bake with an
    /// error instead of blocking it forever.
    pub fn with_wait_timeout(mut self, timeout: Option<Duration>) -> Gpu {
        self.wait_timeout = timeout;
        self
    }

    /// Why the device was lost, or `None` while it works.
    pub fn lost(&self) -> Option<String> {
        self.lost.lock().unwrap().clone()
    }

    /// The error for work of `stage` on a lost device: one line, the stage and
    /// the adapter named, instead of whatever the failing call said.
    pub fn lost_error(&self, stage: &str) -> Option<anyhow::Error> {
        let why = self.lost()?;
        Some(anyhow::anyhow!("{stage}: GPU device lost on {} ({why})", self.adapter.name))
    }

    /// Marks the start of pipeline stage `name` (for the device-loss test hook).
    pub fn enter_stage(&self, name: &str) {
        *self.stage.lock().unwrap() = name.to_string();
    }

    /// Waits for submitted work and turns any GPU error raised so far into an
    /// error naming `stage`. Call at the end of each stage.
    pub fn check(&self, stage: &str) -> Result<()> {
        if let Some(error) = self.lost_error(stage) {
            return Err(error);
        }
        self.wait()?;
        let errors = std::mem::take(&mut *self.errors.lock().unwrap());
        match errors.first() {
            None => Ok(()),
            Some(first) => bail!(
                "{stage}: GPU error on {}: {}{}",
                self.adapter.name,
                one_line(first),
                if errors.len() > 1 { format!(" (and {} more)", errors.len() - 1) } else { String::new() }
            ),
        }
    }

    /// A depth texture that is drawn into and then read by shaders
    /// (shadow maps, hemicubes).
    pub fn depth_target(&self, label: &str, width: u32, height: u32) -> wgpu::Texture {
        self.depth_layers(label, width, height, 1)
    }

    /// As `depth_target`, with `layers` array layers.
    pub fn depth_layers(&self, label: &str, width: u32, height: u32, layers: u32) -> wgpu::Texture {
        self.render_target_layers(label, width, height, layers, wgpu::TextureFormat::Depth32Float)
    }

    /// A 2D texture a render pass writes and a later pass reads.
    pub fn render_target(&self, label: &str, width: u32, height: u32, format: wgpu::TextureFormat) -> wgpu::Texture {
        self.render_target_layers(label, width, height, 1, format)
    }

    fn render_target_layers(
        &self,
        label: &str,
        width: u32,
        height: u32,
        layers: u32,
        format: wgpu::TextureFormat,
    ) -> wgpu::Texture {
        self.device.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size: wgpu::Extent3d { width, height, depth_or_array_layers: layers },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        })
    }

    /// A texture of 4-word records read with `textureLoad`, `width` to a
    /// row, `rows` rows to a layer, laid out layer by layer in `records`.
    pub fn records_texture(
        &self,
        label: &str,
        records: &[[u32; 4]],
        width: u32,
        rows: u32,
        layers: u32,
    ) -> wgpu::Texture {
        use wgpu::util::DeviceExt;
        self.device.create_texture_with_data(
            &self.queue,
            &wgpu::TextureDescriptor {
                label: Some(label),
                size: wgpu::Extent3d { width, height: rows, depth_or_array_layers: layers },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: wgpu::TextureFormat::Rgba32Uint,
                usage: wgpu::TextureUsages::TEXTURE_BINDING,
                view_formats: &[],
            },
            wgpu::util::TextureDataOrder::LayerMajor,
            bytemuck::cast_slice(records),
        )
    }

    /// Blocks until all submitted work has finished. Once the device is lost
    /// it fails at once instead of waiting, and a wait during which the device
    /// is lost fails too.
    pub fn wait(&self) -> Result<()> {
        let lost = || self.lost().map(|why| anyhow::anyhow!("GPU device lost ({why})"));
        if let Some(error) = lost() {
            return Err(error);
        }
        self.lose_device_if_asked();
        self.sample_memory();
        let waited = self.device.poll(wgpu::PollType::Wait { submission_index: None, timeout: self.wait_timeout });
        if let Some(error) = lost() {
            return Err(error);
        }
        match waited {
            Ok(_) => Ok(()),
            Err(wgpu::PollError::Timeout) => {
                // Given up on: later calls fail at once instead of waiting on
                // the same work again, and name the stage as a loss does.
                let limit = self.wait_timeout.map_or(0.0, |t| t.as_secs_f64());
                let why = format!(
                    "no answer to one submission within {limit} s (--gpu-timeout): the driver may be hung, or the \
                     work too large; a smaller --max-atlas-size or fewer --lights make submissions shorter"
                );
                *self.lost.lock().unwrap() = Some(why);
                Err(lost().expect("just marked lost"))
            }
            Err(e) => bail!("GPU wait failed: {e}"),
        }
    }

    /// The test hook: `BAKE_TEST_LOSE_DEVICE=<stage>` (a stage that uses the
    /// GPU: texelize or solve) destroys the device at that stage's first wait,
    /// with its work in flight, as a driver reset or unplugged GPU would.
    /// Tests use it to check that a bake then fails cleanly.
    fn lose_device_if_asked(&self) {
        if self.lose_at.as_deref().is_some_and(|at| *self.stage.lock().unwrap() == at) {
            self.device.destroy();
        }
    }

    /// Bytes of GPU memory wgpu's allocator holds for live buffers and
    /// textures now (`Device::generate_allocator_report`, Vulkan and D3D12);
    /// `None` where the backend gives no report.
    pub fn memory_in_use(&self) -> Option<u64> {
        self.device.generate_allocator_report().map(|r| r.total_allocated_bytes)
    }

    fn sample_memory(&self) -> Option<u64> {
        let now = self.memory_in_use()?;
        self.memory_peak.fetch_max(now, Ordering::Relaxed);
        Some(now)
    }

    /// The largest `memory_in_use` seen at any `wait` (every read-back and
    /// `check` waits) since the last call, then starts over from now. A lower
    /// bound of the true peak: memory allocated and freed between two waits
    /// is not seen. `None` where the backend gives no report.
    pub fn take_memory_peak(&self) -> Option<u64> {
        let now = self.sample_memory()?;
        Some(self.memory_peak.swap(now, Ordering::Relaxed))
    }

    /// Builds the named shader (with the pieces of `shaders/include/` it
    /// uses prepended), once per device.
    pub fn shader(&self, shader: Shader) -> wgpu::ShaderModule {
        self.built.module(shader, || {
            self.device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(shader.stem()),
                source: wgpu::ShaderSource::Wgsl(shader.source().into()),
            })
        })
    }

    /// A bind-group layout of `entries`, built once per device: passes that
    /// ask for equal entries get the same layout, and so the same pipelines
    /// from `compute_pipeline`.
    pub fn bind_group_layout(&self, label: &str, entries: &[wgpu::BindGroupLayoutEntry]) -> wgpu::BindGroupLayout {
        self.built.layout(entries, || {
            self.device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some(label), entries })
        })
    }

    /// A compute pipeline for `entry` of `shader`, labelled with the shader's stem.
    pub fn compute_pipeline(
        &self,
        shader: Shader,
        entry: &str,
        layouts: &[&wgpu::BindGroupLayout],
    ) -> wgpu::ComputePipeline {
        self.compute_pipeline_with(shader, entry, layouts, &[])
    }

    /// As `compute_pipeline`, with values for the shader's `override`
    /// constants. Built once per device for the same shader, entry,
    /// constants and layouts.
    pub fn compute_pipeline_with(
        &self,
        shader: Shader,
        entry: &str,
        layouts: &[&wgpu::BindGroupLayout],
        constants: &[(&str, f64)],
    ) -> wgpu::ComputePipeline {
        self.built.pipeline(shader, entry, constants, layouts, || {
            self.build_compute_pipeline(shader, entry, layouts, constants)
        })
    }

    fn build_compute_pipeline(
        &self,
        shader: Shader,
        entry: &str,
        layouts: &[&wgpu::BindGroupLayout],
        constants: &[(&str, f64)],
    ) -> wgpu::ComputePipeline {
        let module = self.shader(shader);
        let layouts: Vec<Option<&wgpu::BindGroupLayout>> = layouts.iter().map(|l| Some(*l)).collect();
        let layout = self.device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(shader.stem()),
            bind_group_layouts: &layouts,
            immediate_size: 0,
        });
        self.device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(shader.stem()),
            layout: Some(&layout),
            module: &module,
            entry_point: Some(entry),
            compilation_options: wgpu::PipelineCompilationOptions { constants, ..Default::default() },
            cache: None,
        })
    }

    /// A storage buffer holding `parts` one after another (at least one `T`
    /// and 16 bytes, zero-padded: a binding smaller than one element of its
    /// array is refused at dispatch), written straight into the mapped
    /// buffer (no joined copy on the CPU).
    pub fn storage_buffer_of_parts<T: bytemuck::Pod>(
        &self,
        label: &str,
        parts: &[&[T]],
        extra: wgpu::BufferUsages,
    ) -> wgpu::Buffer {
        let size = parts.iter().map(|p| std::mem::size_of_val(*p)).sum::<usize>();
        let size = size.max(std::mem::size_of::<T>()).max(16) as u64;
        self.buffer_of_parts(label, size, parts, wgpu::BufferUsages::STORAGE | extra)
    }

    /// A buffer of `size` bytes (rounded up for copies) holding `parts`
    /// one after another, zero-padded. wgpu's `create_buffer_init` panics
    /// where the device could not allocate it: here its error is in the
    /// sink instead, and `check` ends the stage with it (exit 2).
    fn buffer_of_parts<T: bytemuck::Pod>(
        &self,
        label: &str,
        size: u64,
        parts: &[&[T]],
        usage: wgpu::BufferUsages,
    ) -> wgpu::Buffer {
        let buffer = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: size.next_multiple_of(wgpu::COPY_BUFFER_ALIGNMENT),
            usage,
            mapped_at_creation: true,
        });
        if let Ok(mut mapped) = buffer.get_mapped_range_mut(..) {
            let mut offset = 0;
            for part in parts {
                let bytes: &[u8] = bytemuck::cast_slice(part);
                mapped.slice(offset..offset + bytes.len()).copy_from_slice(bytes);
                offset += bytes.len();
            }
        }
        buffer.unmap();
        buffer
    }

    /// A storage buffer of `count` zeroed elements of `T`, at least one (wgpu
    /// zeroes new buffers: nothing is built on the CPU or uploaded).
    pub fn zeroed_storage_buffer<T: bytemuck::Pod>(
        &self,
        label: &str,
        count: usize,
        extra: wgpu::BufferUsages,
    ) -> wgpu::Buffer {
        self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: (count.max(1) * std::mem::size_of::<T>()).max(16) as u64,
            usage: wgpu::BufferUsages::STORAGE | extra,
            mapped_at_creation: false,
        })
    }

    /// A storage buffer initialised with `data` (at least one `T` and 16
    /// bytes, so empty inputs still bind).
    pub fn storage_buffer<T: bytemuck::Pod>(&self, label: &str, data: &[T], extra: wgpu::BufferUsages) -> wgpu::Buffer {
        self.storage_buffer_of_parts(label, &[data], extra)
    }

    /// A uniform buffer holding one `T`.
    pub fn uniform_buffer<T: bytemuck::Pod>(&self, label: &str, value: &T) -> wgpu::Buffer {
        self.uniform_buffer_with(label, value, wgpu::BufferUsages::empty())
    }

    /// As `uniform_buffer`, with `extra` usages.
    pub fn uniform_buffer_with<T: bytemuck::Pod>(
        &self,
        label: &str,
        value: &T,
        extra: wgpu::BufferUsages,
    ) -> wgpu::Buffer {
        let usage = wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST | extra;
        self.buffer_of_parts(label, std::mem::size_of::<T>() as u64, &[std::slice::from_ref(value)], usage)
    }

    /// Workgroup counts for `items` invocations of `size`, spread over x and y
    /// so that no dimension exceeds the adapter's limit.
    pub fn dispatch_size(&self, items: u32, size: u32) -> (u32, u32) {
        let groups = items.div_ceil(size).max(1);
        let max = self.limits.max_compute_workgroups_per_dimension.max(1);
        if groups <= max { (groups, 1) } else { (max, groups.div_ceil(max)) }
    }
}

/// wgpu's messages span several indented lines; a CLI error is one line.
fn one_line(message: &str) -> String {
    message.lines().map(str::trim).filter(|l| !l.is_empty()).collect::<Vec<_>>().join(": ").replace(":: ", ": ")
}

fn preference_rank(kind: wgpu::DeviceType) -> u8 {
    match kind {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Cpu => 3,
        wgpu::DeviceType::Other => 4,
    }
}

/// A bind-group-layout entry for a storage buffer visible to `stages`.
pub fn storage_entry(binding: u32, read_only: bool, stages: wgpu::ShaderStages) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: stages,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

/// A bind-group-layout entry for a uniform buffer visible to `stages`.
pub fn uniform_entry(binding: u32, stages: wgpu::ShaderStages) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: stages,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

/// The material textures' sample type.
pub const FILTERABLE: wgpu::TextureSampleType = wgpu::TextureSampleType::Float { filterable: true };

/// A bind-group-layout entry for a 2-D array texture read by `sample_type`
/// (the material textures: `FILTERABLE`).
pub fn texture_array_entry(
    binding: u32,
    stages: wgpu::ShaderStages,
    sample_type: wgpu::TextureSampleType,
) -> wgpu::BindGroupLayoutEntry {
    texture_entry(binding, stages, sample_type, wgpu::TextureViewDimension::D2Array)
}

/// A bind-group-layout entry for a depth texture read with `textureLoad`.
pub fn depth_texture_entry(binding: u32, stages: wgpu::ShaderStages) -> wgpu::BindGroupLayoutEntry {
    texture_2d_entry(binding, stages, wgpu::TextureSampleType::Depth)
}

/// A bind-group-layout entry for a 2-D texture read with `textureLoad`.
pub fn texture_2d_entry(
    binding: u32,
    stages: wgpu::ShaderStages,
    sample_type: wgpu::TextureSampleType,
) -> wgpu::BindGroupLayoutEntry {
    texture_entry(binding, stages, sample_type, wgpu::TextureViewDimension::D2)
}

fn texture_entry(
    binding: u32,
    stages: wgpu::ShaderStages,
    sample_type: wgpu::TextureSampleType,
    view_dimension: wgpu::TextureViewDimension,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: stages,
        ty: wgpu::BindingType::Texture { sample_type, view_dimension, multisampled: false },
        count: None,
    }
}

/// A bind-group-layout entry for a filtering sampler.
pub fn sampler_entry(binding: u32, stages: wgpu::ShaderStages) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: stages,
        ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
        count: None,
    }
}

/// Binds `buffers` in order to bindings 0, 1, 2, ...
pub fn bind_buffers(
    gpu: &Gpu,
    label: &str,
    layout: &wgpu::BindGroupLayout,
    buffers: &[&wgpu::Buffer],
) -> wgpu::BindGroup {
    let entries: Vec<wgpu::BindGroupEntry> = buffers
        .iter()
        .enumerate()
        .map(|(i, b)| wgpu::BindGroupEntry { binding: i as u32, resource: b.as_entire_binding() })
        .collect();
    gpu.device.create_bind_group(&wgpu::BindGroupDescriptor { label: Some(label), layout, entries: &entries })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A buffer the device refuses (here, over its size limit) leaves its
    /// error for `check`, which a bake turns into exit 2, rather than a
    /// panic where the buffer is filled.
    #[test]
    fn a_buffer_the_device_cannot_make_is_an_error_not_a_panic() {
        let gpu = Gpu::new(None).expect("an adapter");
        let too_large = gpu.limits.max_buffer_size + 16;
        gpu.buffer_of_parts::<u32>("too large", too_large, &[&[1, 2, 3]], wgpu::BufferUsages::STORAGE);
        let error = gpu.check("upload").expect_err("the device refused the buffer");
        assert!(error.to_string().starts_with("upload: GPU error on "), "{error}");
    }
}
