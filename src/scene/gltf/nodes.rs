//! The default scene's node hierarchy walked into instances: one per node that has a mesh, with
//! its world transform (parents' matrices times its own), the way the glTF tutorial makes one
//! TLAS instance per node with `instanceCustomIndex` the mesh's index; and the first camera met.
use glam::Mat4;

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

/// Instances and the first camera of `document`'s default scene (else its first scene); a node
/// reached twice (a cycle, or a node that two parents name: glTF 2.0 requires the hierarchy to
/// be disjoint trees, and gltf-json 1.4.1 does not check it) is `Err(node)`.
pub(super) fn walk(
    document: &gltf::Document,
) -> Result<(Vec<NodeInstance>, Option<Camera>), usize> {
    let scene = document.default_scene().or_else(|| document.scenes().next());
    let mut out = (Vec::new(), None);
    let roots: Vec<gltf::Node> = match scene {
        Some(s) => s.nodes().collect(),
        None => return Ok(out),
    };
    let mut seen = vec![false; document.nodes().count()];
    let mut stack: Vec<(gltf::Node, Mat4)> =
        roots.into_iter().rev().map(|n| (n, Mat4::IDENTITY)).collect();
    while let Some((node, parent)) = stack.pop() {
        if std::mem::replace(&mut seen[node.index()], true) {
            return Err(node.index());
        }
        let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
        if let Some(m) = node.mesh() {
            out.0.push(NodeInstance { node: node.index(), mesh: m.index(), world });
        }
        if node.camera().is_some() && out.1.is_none() {
            let (_, rot, pos) = world.to_scale_rotation_translation();
            out.1 = Some(Camera {
                node: node.index(),
                world: Mat4::from_rotation_translation(rot, pos),
            });
        }
        let children: Vec<gltf::Node> = node.children().collect();
        stack.extend(children.into_iter().rev().map(|c| (c, world)));
    }
    Ok(out)
}
