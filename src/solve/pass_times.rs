//! Seconds each GPU pass of the bounce pass's batches took, for profiling
//! (`--time-passes`): each pass is then submitted on its own and waited
//! for, which gives up the overlap of a normal run but changes no result.

use std::time::Instant;

use anyhow::Result;
use serde::{Deserialize, Serialize};

use crate::gpu::Gpu;

/// One pass's seconds over the whole run.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct PassSeconds {
    pub pass: String,
    pub seconds: f64,
}

/// A pass of a batch: its name and what records it.
pub(super) type Recorder<'a> = (&'static str, &'a dyn Fn(&mut wgpu::CommandEncoder));

/// The passes' totals, in the order they first ran.
#[derive(Default)]
pub(super) struct PassTimes(Vec<PassSeconds>);

impl PassTimes {
    pub(super) fn add(&mut self, pass: &str, seconds: f64) {
        match self.0.iter_mut().find(|p| p.pass == pass) {
            Some(p) => p.seconds += seconds,
            None => self.0.push(PassSeconds { pass: pass.to_string(), seconds }),
        }
    }

    pub(super) fn into_vec(self) -> Vec<PassSeconds> {
        self.0
    }
}

/// Runs `passes` in order: in one submission, or with `times` each in its
/// own, waited for and timed.
pub(super) fn submit(gpu: &Gpu, passes: &[Recorder], times: Option<&mut PassTimes>) -> Result<()> {
    let Some(times) = times else {
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        for (_, record) in passes {
            record(&mut encoder);
        }
        gpu.queue.submit([encoder.finish()]);
        return Ok(());
    };
    for (name, record) in passes {
        let start = Instant::now();
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        record(&mut encoder);
        gpu.queue.submit([encoder.finish()]);
        gpu.wait()?;
        times.add(name, start.elapsed().as_secs_f64());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pass_run_in_every_batch_is_summed_under_its_name_in_first_run_order() {
        let mut times = PassTimes::default();
        for (pass, seconds) in [("render", 0.5), ("gather", 0.25), ("render", 1.0)] {
            times.add(pass, seconds);
        }
        let names: Vec<_> = times.0.iter().map(|p| (p.pass.as_str(), p.seconds)).collect();
        assert_eq!(names, [("render", 1.5), ("gather", 0.25)]);
    }
}
