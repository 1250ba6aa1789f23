//! Shader modules, bind-group layouts and compute pipelines, each built once
//! per device. A run of many scenes builds every pass's pipelines for the
//! first scene only (on lavapipe a pipeline takes milliseconds to tens of
//! milliseconds of the driver's compiler), and `warm` can build them ahead,
//! on another thread, while the CPU stages of a bake run.
//!
//! A cached pipeline is keyed by the very layouts it was built with; layouts
//! built here are shared by equal entries, so a pass that asks again gets the
//! same layouts and so the same pipeline.

use std::collections::HashMap;
use std::sync::{Arc, Mutex, OnceLock};

use super::Shader;

/// What makes a compute pipeline: the shader, its entry point, the values
/// of its `override` constants (as bits) and its bind-group layouts.
#[derive(PartialEq, Eq, Hash)]
struct PipelineKey {
    shader: Shader,
    entry: String,
    constants: Vec<(String, u64)>,
    layouts: Vec<wgpu::BindGroupLayout>,
}

/// Each value behind its own cell, so that two threads wanting different
/// pipelines build them at once, and two wanting the same one build it once.
type Cells<K, V> = Mutex<HashMap<K, Arc<OnceLock<V>>>>;

#[derive(Default)]
pub(super) struct Built {
    modules: Cells<Shader, wgpu::ShaderModule>,
    layouts: Cells<Vec<wgpu::BindGroupLayoutEntry>, wgpu::BindGroupLayout>,
    pipelines: Cells<PipelineKey, wgpu::ComputePipeline>,
}

/// The value of `key` in `cells`, built by `build` if no thread has yet.
fn get_or_build<K: Eq + std::hash::Hash, V: Clone>(cells: &Cells<K, V>, key: K, build: impl FnOnce() -> V) -> V {
    let cell = cells.lock().unwrap().entry(key).or_default().clone();
    cell.get_or_init(build).clone()
}

impl Built {
    pub(super) fn module(&self, shader: Shader, build: impl FnOnce() -> wgpu::ShaderModule) -> wgpu::ShaderModule {
        get_or_build(&self.modules, shader, build)
    }

    pub(super) fn layout(
        &self,
        entries: &[wgpu::BindGroupLayoutEntry],
        build: impl FnOnce() -> wgpu::BindGroupLayout,
    ) -> wgpu::BindGroupLayout {
        get_or_build(&self.layouts, entries.to_vec(), build)
    }

    pub(super) fn pipeline(
        &self,
        shader: Shader,
        entry: &str,
        constants: &[(&str, f64)],
        layouts: &[&wgpu::BindGroupLayout],
        build: impl FnOnce() -> wgpu::ComputePipeline,
    ) -> wgpu::ComputePipeline {
        let key = PipelineKey {
            shader,
            entry: entry.to_string(),
            constants: constants.iter().map(|(name, value)| (name.to_string(), value.to_bits())).collect(),
            layouts: layouts.iter().map(|l| (*l).clone()).collect(),
        };
        get_or_build(&self.pipelines, key, build)
    }
}
