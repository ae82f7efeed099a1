//! What [`super::reflect`] reads from a module's entry point ([`Reflection`]) and the parts it is
//! made of: descriptor bindings, blocks, ray tracing interface variables, specialization
//! constants, physical-storage-buffer pointer paths and descriptor heap accesses.
use super::ty::{Scalar, Struct, Ty};
use rspirv::spirv::{ExecutionModel, ImageFormat};

/// What one descriptor of a binding is (Vulkan 1.4.360, "Shader Resource and Descriptor Type
/// Correspondence").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Descriptor {
    AccelerationStructure,
    StorageImage(ImageFormat),
    SampledImage,
    CombinedImageSampler,
    Sampler,
    StorageBuffer,
    UniformBuffer,
    UniformTexelBuffer,
    StorageTexelBuffer,
    InputAttachment,
}

/// How many descriptors a binding's variable declares.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Count {
    One,
    Fixed(u32),
    Runtime,
}

/// The last member of a block when it is an array: its offset and `ArrayStride`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Tail {
    pub offset: u32,
    pub stride: u32,
    /// A runtime array (its length is the buffer's).
    pub runtime: bool,
}

/// A block: a buffer's, the push constants' or the shader record's.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Block {
    /// The variable's name ("" when none).
    pub name: String,
    pub ty: Struct,
    /// The lowest member offset.
    pub start: u32,
    /// The end of its fixed part: every member but a trailing runtime array.
    pub end: u32,
    pub tail: Option<Tail>,
}

/// One set/binding variable.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Binding {
    pub set: u32,
    pub binding: u32,
    pub name: String,
    pub descriptor: Descriptor,
    pub count: Count,
    /// A buffer's block.
    pub block: Option<Block>,
    /// A storage buffer or image the module may write: neither the variable nor every member of
    /// its block is `NonWritable` (false for every other kind).
    pub writable: bool,
    /// An `OpAtomic*` instruction's pointer derives from the variable.
    pub atomic: bool,
}

/// A ray payload, callable data or hit attribute variable.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Io {
    pub name: String,
    /// Its `Location` decoration: glslang and DXC write none (`OpTraceRayKHR` and
    /// `OpExecuteCallableKHR` name the variable itself), so it is mostly `None`.
    pub location: Option<u32>,
    pub ty: Ty,
    /// Bytes at scalar alignment ([`Ty::size`]).
    pub size: u32,
}

/// A specialization constant.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SpecConstant {
    pub spec_id: u32,
    pub name: String,
    pub scalar: Scalar,
    /// Its default: the value's bits (a bool 0 or 1, a float its IEEE bits, low word first).
    pub default: u64,
}

/// A `PhysicalStorageBuffer` pointer reachable from a block: how it is reached (`push.scene`,
/// then `SceneDesc.vertices`: one hop per pointer), what it points to.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PointerPath {
    pub path: Vec<String>,
    pub pointee: Ty,
    /// The pointee's bytes: its extent where explicitly laid out, else [`Ty::size`]; a trailing
    /// runtime array counts 0.
    pub size: u32,
    /// The `ArrayStride` of a runtime array pointee, or of a struct pointee's trailing one.
    pub stride: Option<u32>,
}

/// Which descriptor heap an access reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HeapKind {
    Resource,
    Sampler,
}

/// The distance between a heap array's elements.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum HeapStride {
    Bytes(u32),
    /// `OpConstantSizeOfEXT` of this type: the device's descriptor size.
    SizeOf(String),
    /// Not stated by the module (a spec constant or an expression).
    Unknown,
}

/// One kind of access into a descriptor heap: the heap, the element type (`OpTypeBufferEXT`,
/// an image, a sampler, …), the stride of the array indexed, and the byte offset of the member
/// (`OffsetIdEXT`) when the access goes through a struct.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct HeapAccess {
    pub heap: HeapKind,
    pub element: String,
    pub stride: HeapStride,
    pub offset: Option<u32>,
}

/// The descriptor heaps a module reads.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Heap {
    pub capability: bool,
    pub resource: bool,
    pub sampler: bool,
    pub accesses: Vec<HeapAccess>,
}

/// A module's interface at one entry point.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Reflection {
    pub model: ExecutionModel,
    /// raygen, closest_hit, any_hit, miss, intersection, callable, compute, vertex, fragment, or
    /// the execution model's name in lower case.
    pub stage: String,
    pub entry: String,
    /// By (set, binding).
    pub bindings: Vec<Binding>,
    pub heap: Heap,
    pub push: Option<Block>,
    pub record: Option<Block>,
    pub spec_constants: Vec<SpecConstant>,
    pub payloads: Vec<Io>,
    pub incoming_payload: Option<Io>,
    pub callable_data: Vec<Io>,
    pub incoming_callable_data: Option<Io>,
    pub hit_attribute: Option<Io>,
    pub pointers: Vec<PointerPath>,
    /// Every `OpTraceRayKHR` the entry point's call tree executes.
    pub traces: Vec<super::Trace>,
}
