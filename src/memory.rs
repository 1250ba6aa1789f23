//! Measures each stage's memory for the report ([`StageMemory`]): the
//! process's resident set from Linux's `/proc/self/status`, and what wgpu's
//! allocator holds. Measured here, recorded in report.rs.

use crate::gpu::Gpu;
use crate::report::StageMemory;

/// Measures one stage's memory: `start` before it, `finish` after.
pub struct MemoryProbe {
    rss_before: u64,
    reset: bool,
}

impl MemoryProbe {
    /// Records the resident set and resets the high-water marks (CPU and GPU).
    pub fn start(gpu: Option<&Gpu>) -> Option<MemoryProbe> {
        let (rss_before, _) = read_rss()?;
        let reset = std::fs::write("/proc/self/clear_refs", "5").is_ok();
        if let Some(gpu) = gpu {
            gpu.take_memory_peak();
        }
        Some(MemoryProbe { rss_before, reset })
    }

    pub fn finish(self, gpu: Option<&Gpu>) -> Option<StageMemory> {
        let (rss_after, peak) = read_rss()?;
        Some(StageMemory {
            rss_before_bytes: self.rss_before,
            rss_after_bytes: rss_after,
            peak_rss_bytes: peak.max(rss_after).max(if self.reset { 0 } else { self.rss_before }),
            peak_rss_scope: if self.reset { "stage" } else { "process" }.to_string(),
            gpu_peak_bytes: gpu.and_then(Gpu::take_memory_peak),
            gpu_after_bytes: gpu.and_then(Gpu::memory_in_use),
        })
    }
}

/// (VmRSS, VmHWM) in bytes from `/proc/self/status`.
fn read_rss() -> Option<(u64, u64)> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let field = |name: &str| -> Option<u64> {
        let line = status.lines().find(|l| l.starts_with(name))?;
        let kib: u64 = line[name.len()..].trim().trim_end_matches("kB").trim().parse().ok()?;
        Some(kib * 1024)
    };
    Some((field("VmRSS:")?, field("VmHWM:")?))
}
