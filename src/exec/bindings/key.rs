//! The layout key: what a cell's descriptor binding depends on, so that cells with equal keys
//! share one binding (and its set and pipeline layouts).
use crate::model::{DescriptorModel, Resource};
use ash::vk;

/// What a binding is made for (see the fields); its cache key.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct LayoutKey {
    /// Stages that see the bindings and push constants (exactly the pipeline's stages).
    pub stages: vk::ShaderStageFlags,
    pub model: DescriptorModel,
    pub scene_tlas: bool,
    pub probe: Option<Resource>,
    /// Heap model, `heap_access=direct`: the probed array first in the heap.
    pub heap_direct: bool,
    /// `index=dynamic_element`: the packed resource at `probe::PACKED_SLOT`
    /// (`resources::ResourceArray::targets`).
    pub packed: bool,
    /// `scene_layout=per_mesh`: binding 2 holds the mesh buffers (`layout_buffers`), not the
    /// probe resources; in a texture cell (`textures`) binding 3 holds them.
    pub per_mesh: bool,
    /// A `scene_layout` texture cell: binding 2 holds the scene's textures (`layout_textures`).
    pub textures: bool,
}
