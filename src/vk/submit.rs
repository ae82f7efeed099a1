//! Recording and submitting one command buffer and waiting for it with a deadline. A fence wait
//! that runs out is a [`Waited::TimedOut`] (the cell hangs), not an error; a lost device is
//! `VkError::DeviceLost`. The submitter sums the time it spent submitted-and-waiting
//! ([`Submitter::waited`]): the queue waits that a run's own time (`timing.own_ms`) leaves out.
use super::error::{VkError, VkResultExt};
use super::Gpu;
use ash::vk;
use std::cell::Cell;
use std::time::{Duration, Instant};

pub struct Submitter {
    pool: vk::CommandPool,
    cmd: vk::CommandBuffer,
    fence: vk::Fence,
    /// Submit-to-fence time of every submission so far, a timed-out wait's included.
    waited: Cell<Duration>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Waited {
    Done(Duration),
    TimedOut,
}

impl Submitter {
    pub fn new(gpu: &Gpu) -> Result<Self, VkError> {
        let d = &gpu.device;
        let pool = unsafe {
            d.create_command_pool(
                &vk::CommandPoolCreateInfo::default()
                    .queue_family_index(gpu.queue_family)
                    .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER),
                None,
            )
        }
        .at("vkCreateCommandPool")?;
        let cmd = unsafe {
            d.allocate_command_buffers(
                &vk::CommandBufferAllocateInfo::default()
                    .command_pool(pool)
                    .level(vk::CommandBufferLevel::PRIMARY)
                    .command_buffer_count(1),
            )
        }
        .at("vkAllocateCommandBuffers")?[0];
        let fence =
            unsafe { d.create_fence(&vk::FenceCreateInfo::default(), None) }.at("vkCreateFence")?;
        Ok(Self { pool, cmd, fence, waited: Cell::new(Duration::ZERO) })
    }

    /// Record with `f`, submit, and wait up to `timeout`.
    pub fn run(
        &self,
        gpu: &Gpu,
        timeout: Duration,
        f: impl FnOnce(vk::CommandBuffer),
    ) -> Result<Waited, VkError> {
        self.record(gpu, f)?;
        self.submit_and_wait(gpu, timeout, None)
    }

    /// [`Submitter::run`] with the submission held behind `gate`, a timeline semaphore at 0
    /// (the device's `timelineSemaphore` enabled): its work cannot start before the host
    /// signals 1, which happens only once the wait has run out — a submission past its
    /// deadline, whatever the deadline and however fast the device (a test hook's stalled
    /// GPU). Vulkan 1.4.360, Command Buffers, Queue Submission: "When using timeline
    /// semaphores, wait-before-signal behavior is well-defined and applications can submit work
    /// via vkQueueSubmit defining a timeline semaphore wait operation before submitting a
    /// corresponding semaphore signal operation". With `release` the host then signals and
    /// waits for the work without a deadline, so nothing is freed under it; without, the work
    /// stays pending for good (a hung GPU: the caller must leave the device as it is). The
    /// result is the first wait's; an error in recording, submitting or that wait returns at
    /// once (nothing was submitted, or the device is lost).
    pub fn run_held(
        &self,
        gpu: &Gpu,
        timeout: Duration,
        (gate, release): (vk::Semaphore, bool),
        f: impl FnOnce(vk::CommandBuffer),
    ) -> Result<Waited, VkError> {
        self.record(gpu, f)?;
        let first = self.submit_and_wait(gpu, timeout, Some(gate))?;
        if release {
            let d = &gpu.device;
            let info = vk::SemaphoreSignalInfo::default().semaphore(gate).value(1);
            unsafe { d.signal_semaphore(&info) }.at("vkSignalSemaphore")?;
            unsafe { d.wait_for_fences(&[self.fence], true, u64::MAX) }.at("vkWaitForFences")?;
        }
        Ok(first)
    }

    fn record(&self, gpu: &Gpu, f: impl FnOnce(vk::CommandBuffer)) -> Result<(), VkError> {
        let d = &gpu.device;
        unsafe {
            d.reset_command_buffer(self.cmd, vk::CommandBufferResetFlags::empty())
                .at("vkResetCommandBuffer")?;
            d.begin_command_buffer(
                self.cmd,
                &vk::CommandBufferBeginInfo::default()
                    .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT),
            )
            .at("vkBeginCommandBuffer")?;
        }
        f(self.cmd);
        unsafe { d.end_command_buffer(self.cmd) }.at("vkEndCommandBuffer")
    }

    /// Submits the recorded buffer (after `gate` reaches 1, where given) and waits up to
    /// `timeout`.
    fn submit_and_wait(
        &self,
        gpu: &Gpu,
        timeout: Duration,
        gate: Option<vk::Semaphore>,
    ) -> Result<Waited, VkError> {
        let d = &gpu.device;
        unsafe { d.reset_fences(&[self.fence]) }.at("vkResetFences")?;
        let cmds = [self.cmd];
        let (gates, values, stages) = match gate {
            Some(g) => (vec![g], vec![1u64], vec![vk::PipelineStageFlags::ALL_COMMANDS]),
            None => (vec![], vec![], vec![]),
        };
        let mut timeline =
            vk::TimelineSemaphoreSubmitInfo::default().wait_semaphore_values(&values);
        let mut submit = vk::SubmitInfo::default().command_buffers(&cmds);
        if gate.is_some() {
            submit = submit
                .wait_semaphores(&gates)
                .wait_dst_stage_mask(&stages)
                .push_next(&mut timeline);
        }
        let start = Instant::now();
        unsafe { d.queue_submit(gpu.queue, &[submit], self.fence) }.at("vkQueueSubmit")?;
        let ns = timeout.as_nanos().min(u64::MAX as u128) as u64;
        let r = unsafe { d.wait_for_fences(&[self.fence], true, ns) };
        let took = start.elapsed();
        self.waited.set(self.waited.get() + took);
        match r {
            Ok(()) => Ok(Waited::Done(took)),
            Err(vk::Result::TIMEOUT) => Ok(Waited::TimedOut),
            Err(e) => Err(VkError::from_result("vkWaitForFences", e)),
        }
    }

    /// A timeline semaphore at 0, for [`Submitter::run_held`]; the caller destroys it.
    pub fn gate(gpu: &Gpu) -> Result<vk::Semaphore, VkError> {
        let mut ty = vk::SemaphoreTypeCreateInfo::default()
            .semaphore_type(vk::SemaphoreType::TIMELINE)
            .initial_value(0);
        let info = vk::SemaphoreCreateInfo::default().push_next(&mut ty);
        unsafe { gpu.device.create_semaphore(&info, None) }.at("vkCreateSemaphore")
    }

    /// The submit-to-fence time of every submission so far (a wait that ran out counts whole):
    /// the time the calling thread spent on the queue rather than on its own work.
    pub fn waited(&self) -> Duration {
        self.waited.get()
    }

    pub fn destroy(&self, gpu: &Gpu) {
        unsafe {
            gpu.device.destroy_fence(self.fence, None);
            gpu.device.destroy_command_pool(self.pool, None);
        }
    }
}
