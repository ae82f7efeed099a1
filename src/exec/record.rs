//! Recording one cell's GPU work into a command buffer, for each of the three pipeline kinds: a
//! ray tracing pipeline's trace over the image, a compute dispatch of 8×8 groups, or a graphics
//! draw of one quad per tile into the color target under dynamic rendering; then the barrier that
//! makes the records visible to the host.
use super::bindings::Binding;
use super::pipeline::Pipeline;
use crate::probe;
use crate::shadergen::PipelineKind;
use crate::vk::memory::{transition, Image, Transition};
use crate::vk::Gpu;
use ash::vk;

/// One cell's GPU work: its pipeline, bindings and push constants over a `size` (w, h) launch.
pub(super) struct Work<'a> {
    pub(super) pipe: &'a Pipeline,
    pub(super) binding: &'a Binding,
    pub(super) stages: vk::ShaderStageFlags,
    pub(super) pc: &'a [u8],
    pub(super) color: Option<&'a Image>,
    pub(super) size: (u32, u32),
}

impl Work<'_> {
    /// Record the trace, dispatch or draw into `cmd` (in the recording state).
    pub(super) unsafe fn record(&self, gpu: &Gpu, cmd: vk::CommandBuffer) {
        match self.pipe.kind {
            PipelineKind::RayTracing => self.trace_rays(gpu, cmd),
            PipelineKind::Compute => self.dispatch(gpu, cmd),
            PipelineKind::Graphics => self.draw(gpu, cmd),
        }
    }

    /// Bind the cell's descriptors and pipeline at `point`, and push its push constants.
    unsafe fn bind(&self, gpu: &Gpu, cmd: vk::CommandBuffer, point: vk::PipelineBindPoint) {
        self.binding.bind(gpu, cmd, point);
        gpu.device.cmd_bind_pipeline(cmd, point, self.pipe.raw);
        self.binding.push(gpu, cmd, self.stages, self.pc);
    }

    /// One ray per pixel through the pipeline's shader binding table.
    unsafe fn trace_rays(&self, gpu: &Gpu, cmd: vk::CommandBuffer) {
        let (w, h) = self.size;
        self.bind(gpu, cmd, vk::PipelineBindPoint::RAY_TRACING_KHR);
        let sbt = self.pipe.sbt.as_ref().expect("RT pipelines have an SBT");
        gpu.rt.as_ref().expect("RT enabled").cmd_trace_rays(
            cmd,
            &sbt.raygen,
            &sbt.miss,
            &sbt.hit,
            &sbt.callable,
            w,
            h,
            1,
        );
    }

    /// One invocation per pixel, in 8×8 work groups.
    unsafe fn dispatch(&self, gpu: &Gpu, cmd: vk::CommandBuffer) {
        let (w, h) = self.size;
        self.bind(gpu, cmd, vk::PipelineBindPoint::COMPUTE);
        gpu.device.cmd_dispatch(cmd, w.div_ceil(8), h.div_ceil(8), 1);
    }

    /// One quad (6 vertices) per `probe::TILE`² tile, rendered into the color target.
    unsafe fn draw(&self, gpu: &Gpu, cmd: vk::CommandBuffer) {
        let (d, (w, h)) = (&gpu.device, self.size);
        let img = self.color.expect("color target created");
        let area = vk::Rect2D {
            offset: vk::Offset2D::default(),
            extent: vk::Extent2D { width: w, height: h },
        };
        begin_rendering(gpu, cmd, img, area);
        self.bind(gpu, cmd, vk::PipelineBindPoint::GRAPHICS);
        d.cmd_set_viewport(
            cmd,
            0,
            &[vk::Viewport {
                x: 0.0,
                y: 0.0,
                width: w as f32,
                height: h as f32,
                min_depth: 0.0,
                max_depth: 1.0,
            }],
        );
        d.cmd_set_scissor(cmd, 0, &[area]);
        d.cmd_draw(cmd, 6, (w / probe::TILE) * (h / probe::TILE), 0, 0);
        d.cmd_end_rendering(cmd);
    }
}

/// Move the color target `img` to the attachment layout and begin rendering into `area` of it,
/// cleared.
unsafe fn begin_rendering(gpu: &Gpu, cmd: vk::CommandBuffer, img: &Image, area: vk::Rect2D) {
    let top =
        (vk::ImageLayout::UNDEFINED, vk::AccessFlags::empty(), vk::PipelineStageFlags::TOP_OF_PIPE);
    let att = (
        vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
        vk::AccessFlags::COLOR_ATTACHMENT_WRITE,
        vk::PipelineStageFlags::COLOR_ATTACHMENT_OUTPUT,
    );
    transition(gpu, cmd, img.raw, Transition { from: top, to: att });
    let att = [vk::RenderingAttachmentInfo::default()
        .image_view(img.view)
        .image_layout(vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL)
        .load_op(vk::AttachmentLoadOp::CLEAR)
        .store_op(vk::AttachmentStoreOp::STORE)];
    gpu.device.cmd_begin_rendering(
        cmd,
        &vk::RenderingInfo::default().render_area(area).layer_count(1).color_attachments(&att),
    );
}

/// Every write of the work made visible to the host, which reads the records mapped.
pub(super) unsafe fn to_host(gpu: &Gpu, cmd: vk::CommandBuffer) {
    let to_host = [vk::MemoryBarrier::default()
        .src_access_mask(vk::AccessFlags::MEMORY_WRITE)
        .dst_access_mask(vk::AccessFlags::HOST_READ)];
    gpu.device.cmd_pipeline_barrier(
        cmd,
        vk::PipelineStageFlags::ALL_COMMANDS,
        vk::PipelineStageFlags::HOST,
        vk::DependencyFlags::empty(),
        &to_host,
        &[],
        &[],
    );
}
