//! Recording and submitting one command buffer and waiting for it with a deadline. A fence wait
//! that runs out is a [`Waited::TimedOut`] (the cell hangs), not an error; a lost device is
//! `VkError::DeviceLost`.
use super::error::{VkError, VkResultExt};
use super::Gpu;
use ash::vk;
use std::time::{Duration, Instant};

pub struct Submitter {
    pool: vk::CommandPool,
    cmd: vk::CommandBuffer,
    fence: vk::Fence,
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
        Ok(Self { pool, cmd, fence })
    }

    /// Record with `f`, submit, and wait up to `timeout`.
    pub fn run(
        &self,
        gpu: &Gpu,
        timeout: Duration,
        f: impl FnOnce(vk::CommandBuffer),
    ) -> Result<Waited, VkError> {
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
        unsafe { d.end_command_buffer(self.cmd) }.at("vkEndCommandBuffer")?;
        unsafe { d.reset_fences(&[self.fence]) }.at("vkResetFences")?;
        let cmds = [self.cmd];
        let submit = [vk::SubmitInfo::default().command_buffers(&cmds)];
        let start = Instant::now();
        unsafe { d.queue_submit(gpu.queue, &submit, self.fence) }.at("vkQueueSubmit")?;
        let ns = timeout.as_nanos().min(u64::MAX as u128) as u64;
        match unsafe { d.wait_for_fences(&[self.fence], true, ns) } {
            Ok(()) => Ok(Waited::Done(start.elapsed())),
            Err(vk::Result::TIMEOUT) => Ok(Waited::TimedOut),
            Err(e) => Err(VkError::from_result("vkWaitForFences", e)),
        }
    }

    pub fn destroy(&self, gpu: &Gpu) {
        unsafe {
            gpu.device.destroy_fence(self.fence, None);
            gpu.device.destroy_command_pool(self.pool, None);
        }
    }
}
