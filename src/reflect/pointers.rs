//! Every `PhysicalStorageBuffer` pointer reachable from a block ([`paths`]): the member path to
//! it from the block (`push.scene`), then from each pointee to the next (`SceneDesc.vertices`).
//! Only typed pointer members count: a `uint64_t` or `uvec2` address that the shader converts
//! to a pointer (`OpConvertUToPtr`, `OpBitcast`) is just an integer in the block, and where it
//! points cannot be known from the types.
use super::reflection::PointerPath;
use super::ty::Ty;
use rspirv::spirv::StorageClass;

/// Pointer hops followed from one block at most (a pointee met again on a path ends it).
const MAX_HOPS: usize = 16;
/// Paths reported for one block at most.
const MAX_PATHS: usize = 256;

/// The pointer paths from `root` (a block's type, reached as `name`).
pub fn paths(name: &str, root: &Ty) -> Vec<PointerPath> {
    let mut out = Vec::new();
    walk(root, name.to_string(), &mut Vec::new(), &mut Vec::new(), &mut out);
    out
}

/// Visit `ty`, reached as `at` inside the current hop, after the hops `hops`; `seen` the
/// pointees on this path.
fn walk(
    ty: &Ty,
    at: String,
    hops: &mut Vec<String>,
    seen: &mut Vec<Ty>,
    out: &mut Vec<PointerPath>,
) {
    if out.len() >= MAX_PATHS {
        return;
    }
    match ty {
        Ty::Struct(s) => {
            for (k, m) in s.members.iter().enumerate() {
                let member = if m.name.is_empty() { format!("m{k}") } else { m.name.clone() };
                walk(&m.ty, format!("{at}.{member}"), hops, seen, out);
            }
        }
        Ty::Array { elem, .. } | Ty::RuntimeArray { elem, .. } => {
            walk(elem, format!("{at}[]"), hops, seen, out)
        }
        Ty::Pointer { class: StorageClass::PhysicalStorageBuffer, pointee: Some(p) } => {
            hops.push(at);
            out.push(PointerPath {
                path: hops.clone(),
                pointee: (**p).clone(),
                size: p.extent(None).unwrap_or_else(|| tight(p)),
                stride: stride(p),
            });
            if hops.len() < MAX_HOPS && !seen.contains(p) {
                seen.push((**p).clone());
                let next = match &**p {
                    Ty::Struct(s) if !s.name.is_empty() => s.name.clone(),
                    _ => "*".to_string(),
                };
                walk(p, next, hops, seen, out);
                seen.pop();
            }
            hops.pop();
        }
        _ => {}
    }
}

/// The bytes of a struct up to its trailing runtime array (offsets honoured), else its size.
fn tight(t: &Ty) -> u32 {
    match t {
        Ty::Struct(s) => s
            .members
            .iter()
            .filter(|m| !matches!(m.ty, Ty::RuntimeArray { .. }))
            .map(|m| m.offset.unwrap_or(0) + m.ty.extent(m.matrix).unwrap_or_else(|| m.ty.size()))
            .max()
            .unwrap_or(0),
        other => other.size(),
    }
}

/// The stride of a runtime array pointee, or of a struct pointee's trailing runtime array.
fn stride(t: &Ty) -> Option<u32> {
    match t {
        Ty::RuntimeArray { stride, .. } => *stride,
        Ty::Struct(s) => match &s.members.last()?.ty {
            Ty::RuntimeArray { stride, .. } => *stride,
            _ => None,
        },
        _ => None,
    }
}
