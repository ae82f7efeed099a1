//! The default scene's node hierarchy walked into instances: one per node that has a mesh, with
//! its world transform (parents' matrices times its own), the way the glTF tutorial makes one
//! TLAS instance per node with `instanceCustomIndex` the mesh's index; and the first camera met.
use super::doc::{Node, Root};
use glam::{Mat4, Vec4};

/// A node with a mesh, placed in the world.
#[derive(Clone, Debug, PartialEq)]
pub struct NodeInstance {
    pub node: usize,
    pub mesh: usize,
    /// Object to world, column-major.
    pub world: Mat4,
}

/// The first camera of the hierarchy: its node's world matrix (the camera looks along its local
/// −z, y up), without scale.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    pub node: usize,
    pub world: Mat4,
}

/// Instances and the first camera of `root`'s default scene (else its first scene), its indices
/// validated ([`super::validate`]); a node reached twice (a cycle, or a node that two parents
/// name: glTF 2.0, "Nodes and Hierarchy", requires the hierarchy to be disjoint trees) is
/// `Err(node)`.
pub(super) fn walk(root: &Root) -> Result<(Vec<NodeInstance>, Option<Camera>), usize> {
    let mut out = (Vec::new(), None);
    let Some(scene) = root.scene.or((!root.scenes.is_empty()).then_some(0)) else {
        return Ok(out);
    };
    let mut seen = vec![false; root.nodes.len()];
    let mut stack: Vec<(usize, Mat4)> =
        root.scenes[scene].nodes.iter().rev().map(|&n| (n, Mat4::IDENTITY)).collect();
    while let Some((n, parent)) = stack.pop() {
        if std::mem::replace(&mut seen[n], true) {
            return Err(n);
        }
        let node = &root.nodes[n];
        let world = parent * local(node);
        if let Some(m) = node.mesh {
            out.0.push(NodeInstance { node: n, mesh: m, world });
        }
        if node.camera.is_some() && out.1.is_none() {
            let (_, rot, pos) = world.to_scale_rotation_translation();
            out.1 = Some(Camera { node: n, world: Mat4::from_rotation_translation(rot, pos) });
        }
        stack.extend(node.children.iter().rev().map(|&c| (c, world)));
    }
    Ok(out)
}

/// A node's local matrix (glTF 2.0, "Transformations"): its `matrix` (column-major), else
/// `T * R * S` from its TRS properties, the rotation a unit quaternion XYZW. Computed with the
/// same arithmetic as the `gltf` crate rtprobe read scenes with before, so that a scene's
/// instances are bit for bit what they were.
fn local(node: &Node) -> Mat4 {
    if let Some(m) = node.matrix {
        return Mat4::from_cols_array(&m);
    }
    let [x, y, z, w] = node.rotation;
    let (x2, y2, z2) = (x + x, y + y, z + z);
    let (xx2, xy2, xz2) = (x2 * x, x2 * y, x2 * z);
    let (yy2, yz2, zz2) = (y2 * y, y2 * z, z2 * z);
    let (sy2, sz2, sx2) = (y2 * w, z2 * w, x2 * w);
    let [sx, sy, sz] = node.scale;
    let [tx, ty, tz] = node.translation;
    Mat4::from_cols(
        Vec4::new(1.0 - yy2 - zz2, xy2 + sz2, xz2 - sy2, 0.0) * sx,
        Vec4::new(xy2 - sz2, 1.0 - xx2 - zz2, yz2 + sx2, 0.0) * sy,
        Vec4::new(xz2 + sy2, yz2 - sx2, 1.0 - xx2 - yy2, 0.0) * sz,
        Vec4::new(tx, ty, tz, 1.0),
    )
}
