//! The worker: `rtprobe __worker JOB.json`. Creates one device with exactly what its cells need,
//! runs the cells in order and reports each on stdout. After a device loss, a timeout or a crash
//! the device is unusable, so it reports and exits at once (`_exit`, skipping destructors that
//! could block on a hung queue).
use super::protocol::{WorkerJob, WorkerMsg};
use crate::exec::{ExecOptions, Executor};
use crate::matrix::cell::Workaround;
use crate::matrix::{AsAccess, Canary, Cell, DescriptorModel, Resource, Stage};
use crate::vk::{features, Gpu, Instance, InstanceOptions, Requirements};
use std::io::Write;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// What the device must enable for `cells`.
pub fn requirements(info: &crate::vk::DeviceInfo, cells: &[Cell]) -> Requirements {
    let any = |f: &dyn Fn(&Cell) -> bool| cells.iter().any(f);
    let fragment = any(&|c| c.stage == Stage::Fragment);
    Requirements {
        rt_pipeline: any(&|c| c.stage.is_ray_tracing()),
        ray_query: any(&|c| c.resource == Resource::AccelerationStructure && !c.stage.can_trace_ray()),
        buffer_device_address: true,
        descriptor_indexing: true,
        descriptor_buffer: any(&|c| c.descriptor_model == DescriptorModel::DescriptorBuffer),
        descriptor_heap: any(&|c| c.descriptor_model == DescriptorModel::DescriptorHeap),
        untyped_pointers: any(&|c| c.heap_access == Some(crate::matrix::HeapAccess::Direct)),
        device_fault: info.features.fault.is_some_and(|f| f.device_fault == ash::vk::TRUE),
        int64: any(&|c| {
            matches!(c.as_access, Some(AsAccess::Address | AsAccess::AddressPatched))
                || matches!(c.patch, Some(Workaround::AsToAddress | Workaround::SsboToAddress))
                || c.canary == Some(Canary::InvalidAddress)
        }),
        fragment_stores: fragment,
        dynamic_rendering: fragment,
    }
}

fn send(msg: &WorkerMsg) {
    let mut out = std::io::stdout().lock();
    let _ = serde_json::to_writer(&mut out, msg);
    let _ = out.write_all(b"\n");
    let _ = out.flush();
}

/// Runs the job; returns the process exit code (the process may also `_exit` early).
pub fn main(job_path: &std::path::Path) -> u8 {
    let job: WorkerJob = match std::fs::read(job_path).map_err(|e| e.to_string()).and_then(|b| serde_json::from_slice(&b).map_err(|e| e.to_string())) {
        Ok(j) => j,
        Err(e) => {
            send(&WorkerMsg::Fatal { message: format!("cannot read job {}: {e}", job_path.display()) });
            return 2;
        }
    };
    let t = Instant::now();
    let setup = (|| -> Result<Executor, String> {
        let inst = Arc::new(Instance::new(&InstanceOptions { validate: job.validate }).map_err(|e| e.to_string())?);
        let all = features::query_all(&inst).map_err(|e| e.to_string())?;
        let info = all.get(job.device_index).ok_or_else(|| format!("device {} vanished", job.device_index))?.clone();
        let req = requirements(&info, &job.cells);
        let gpu = Gpu::new(inst, info, req).map_err(|e| e.to_string())?;
        let opts = ExecOptions { timeout: Duration::from_millis(job.fence_timeout_ms), corrupt_expected: job.corrupt_expected, dump: job.dump.clone() };
        Executor::new(gpu, &job.scene, opts).map_err(|e| e.to_string())
    })();
    let mut exec = match setup {
        Ok(e) => e,
        Err(message) => {
            send(&WorkerMsg::Fatal { message });
            return 3;
        }
    };
    send(&WorkerMsg::Ready { device_ms: t.elapsed().as_secs_f64() * 1e3 - exec.reference_ms, reference_ms: exec.reference_ms });
    for cell in &job.cells {
        let id = cell.id();
        send(&WorkerMsg::Start { cell: id.clone() });
        let result = exec.run(cell);
        let ends = result.outcome.ends_worker();
        send(&WorkerMsg::Result { cell: id, result });
        if ends {
            // The device is lost or hung: do not run destructors that may wait on it.
            unsafe { libc::_exit(0) };
        }
    }
    drop(exec);
    0
}
