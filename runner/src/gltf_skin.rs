//! Skinned glTF meshes (characters, rigged props) placed as the file poses them: each vertex
//! moved by its joints' matrices (joint's world transform × inverse bind matrix) weighted
//! by `WEIGHTS_0`, the node's own transform ignored (the specification's rule). Animations
//! are not played: the pose is the one the nodes' transforms give.
use glam::Mat4;
use gltf::Semantic;

use crate::bail;
use crate::error::Result;
use crate::gltf_attributes as vertex;

/// Each node's world transform, whether or not the scene's tree reaches it (a skin's joints
/// may hang elsewhere): its ancestors' transforms times its own.
pub fn world_transforms(doc: &gltf::Document) -> Vec<Mat4> {
    let count = doc.nodes().len();
    let mut parent = vec![None; count];
    for node in doc.nodes() {
        for child in node.children() {
            parent[child.index()].get_or_insert(node.index());
        }
    }
    let local: Vec<Mat4> = doc
        .nodes()
        .map(|n| Mat4::from_cols_array_2d(&n.transform().matrix()))
        .collect();
    (0..count)
        .map(|mut n| {
            let mut world = local[n];
            // At most `count` steps up: a file whose hierarchy loops stops there.
            for _ in 0..count {
                let Some(p) = parent[n] else { break };
                world = local[p] * world;
                n = p;
            }
            world
        })
        .collect()
}

/// A skinned primitive's joints and each vertex's four influences.
pub struct Skinning {
    /// Joint k's world transform × its inverse bind matrix.
    joints: Vec<Mat4>,
    influences: Vec<([u16; 4], [f32; 4])>,
}

impl Skinning {
    /// The skinning of primitive `prim` of `node` (with `vertices` positions), or None
    /// where the node has no skin or the primitive no `JOINTS_0` and `WEIGHTS_0`. A joint
    /// index past the skin's joints, or influences for fewer vertices than it has, is an
    /// error naming `at`.
    pub fn read(
        node: &gltf::Node,
        prim: &gltf::Primitive,
        worlds: &[Mat4],
        buffers: &[gltf::buffer::Data],
        vertices: usize,
        at: &str,
    ) -> Result<Option<Self>> {
        let Some(skin) = node.skin() else {
            return Ok(None);
        };
        let (Some(joints_accessor), Some(weights_accessor)) = (
            prim.get(&Semantic::Joints(0)),
            prim.get(&Semantic::Weights(0)),
        ) else {
            return Ok(None);
        };
        let data = |b: gltf::Buffer| buffers.get(b.index()).map(|d| &d.0[..]);
        let inverse_binds: Vec<Mat4> = match (
            skin.reader(data).read_inverse_bind_matrices(),
            skin.inverse_bind_matrices(),
        ) {
            (Some(m), _) => m.map(|m| Mat4::from_cols_array_2d(&m)).collect(),
            (None, None) => vec![Mat4::IDENTITY; skin.joints().len()],
            (None, Some(a)) => {
                return Err(vertex::unreadable(
                    at,
                    "inverseBindMatrices",
                    &a,
                    vertex::OUTSIDE,
                ))
            }
        };
        let joints: Vec<Mat4> = skin
            .joints()
            .zip(
                inverse_binds
                    .iter()
                    .chain(std::iter::repeat(&Mat4::IDENTITY)),
            )
            .map(|(joint, inverse_bind)| worlds[joint.index()] * *inverse_bind)
            .collect();
        let reader = prim.reader(data);
        let Some(indices) = reader.read_joints(0) else {
            return Err(vertex::unreadable(
                at,
                "JOINTS_0",
                &joints_accessor,
                vertex::OUTSIDE,
            ));
        };
        let Some(weights) = reader.read_weights(0) else {
            return Err(vertex::unreadable(
                at,
                "WEIGHTS_0",
                &weights_accessor,
                vertex::OUTSIDE,
            ));
        };
        let influences: Vec<([u16; 4], [f32; 4])> =
            indices.into_u16().zip(weights.into_f32()).collect();
        if influences.len() < vertices {
            bail!(
                "{at}: JOINTS_0 and WEIGHTS_0 hold {} vertices of its {vertices}",
                influences.len()
            );
        }
        if let Some(&(j, _)) = influences
            .iter()
            .find(|(j, w)| (0..4).any(|k| w[k] != 0.0 && j[k] as usize >= joints.len()))
        {
            bail!(
                "{at}: JOINTS_0 names joint {} of a skin with {}",
                j.iter().max().unwrap(),
                joints.len()
            );
        }
        Ok(Some(Self { joints, influences }))
    }

    /// Vertex `v`'s transform: its joints' matrices by their weights (normalized to sum to
    /// 1, as the specification asks of files; without any weight, its first joint's).
    pub fn matrix(&self, v: usize) -> Mat4 {
        let (joints, weights) = self.influences[v];
        let total: f32 = weights.iter().sum();
        if total.is_nan() || total <= 0.0 || total.is_infinite() {
            return self
                .joints
                .get(joints[0] as usize)
                .copied()
                .unwrap_or(Mat4::IDENTITY);
        }
        let mut m = Mat4::ZERO;
        for k in 0..4 {
            if weights[k] != 0.0 {
                m += self.joints[joints[k] as usize] * (weights[k] / total);
            }
        }
        m
    }
}
