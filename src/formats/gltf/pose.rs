//! The pose a glTF file shows when nothing animates it, as three.js and Blender
//! show it at load: morph targets blended by their default weights (the node's
//! `weights`, else the mesh's), and skinned meshes placed by their joints in the
//! nodes' own transforms (linear blend skinning: each vertex moved by the weighted
//! sum of its joints' world transforms times their inverse bind matrices). The
//! glTF specification says a skinned mesh's node transform is ignored: only its
//! joints place it.

use glam::{Mat3, Mat4};

use super::{AccessorProblem, Expected, check_accessor, read_floats};
use crate::math::Vec3;

/// The world transform of every node in the nodes' own (default) transforms, by
/// node index. A node reached from two parents takes the first; one outside every
/// tree is placed by its own transform.
pub(super) fn node_worlds(document: &gltf::Document) -> Vec<Mat4> {
    let count = document.nodes().len();
    let mut parent = vec![None; count];
    for node in document.nodes() {
        for child in node.children() {
            parent[child.index()].get_or_insert(node.index());
        }
    }
    let local: Vec<Mat4> = document
        .nodes()
        .map(|n| Mat4::from_cols_array_2d(&n.transform().matrix()))
        .collect();
    let mut world: Vec<Option<Mat4>> = vec![None; count];
    for start in 0..count {
        // The chain of ancestors not placed yet, then placed from the top down (no
        // recursion: a hierarchy may be deep; cycles were refused before).
        let mut chain = Vec::new();
        let mut at = Some(start);
        while let Some(node) = at {
            if world[node].is_some() || chain.len() > count {
                break;
            }
            chain.push(node);
            at = parent[node];
        }
        for &node in chain.iter().rev() {
            let above = parent[node]
                .and_then(|p| world[p])
                .unwrap_or(Mat4::IDENTITY);
            world[node] = Some(above * local[node]);
        }
    }
    world
        .into_iter()
        .map(|m| m.unwrap_or(Mat4::IDENTITY))
        .collect()
}

const INVERSE_BIND: Expected = Expected {
    what: "inverseBindMatrices",
    types: &[gltf::accessor::DataType::F32],
    dimensions: gltf::accessor::Dimensions::Mat4,
};
const JOINTS: Expected = Expected {
    what: "JOINTS",
    types: &[gltf::accessor::DataType::U8, gltf::accessor::DataType::U16],
    dimensions: gltf::accessor::Dimensions::Vec4,
};
const WEIGHTS: Expected = Expected {
    what: "WEIGHTS",
    types: &[
        gltf::accessor::DataType::F32,
        gltf::accessor::DataType::U8,
        gltf::accessor::DataType::U16,
    ],
    dimensions: gltf::accessor::Dimensions::Vec4,
};
const TARGET: Expected = Expected {
    what: "morph target",
    types: super::QUANTIZED,
    dimensions: gltf::accessor::Dimensions::Vec3,
};

/// A problem of an accessor as a message (type or bounds alike: the pose is then
/// not applied, and the mesh is read as it is).
fn checked(
    accessor: &gltf::Accessor<'_>,
    expected: &Expected,
    buffers: &[Vec<u8>],
) -> Result<(), String> {
    check_accessor(accessor, expected, buffers).map_err(|p| match p {
        AccessorProblem::Type(m) | AccessorProblem::Bounds(m) => m,
    })
}

/// Each joint's skinning matrix, its world transform (`worlds`) times its inverse
/// bind matrix (the identity when the skin gives none).
///
/// # Errors
/// A message when the inverse bind matrices cannot be read or are too few.
pub(super) fn joint_matrices(
    skin: &gltf::Skin<'_>,
    worlds: &[Mat4],
    buffers: &[Vec<u8>],
) -> Result<Vec<Mat4>, String> {
    let joints: Vec<Mat4> = skin
        .joints()
        .map(|j| worlds.get(j.index()).copied().unwrap_or(Mat4::IDENTITY))
        .collect();
    let Some(accessor) = skin.inverse_bind_matrices() else {
        return Ok(joints);
    };
    checked(&accessor, &INVERSE_BIND, buffers)?;
    let inverse: Vec<Mat4> = gltf::accessor::Iter::<[[f32; 4]; 4]>::new(accessor, |b| {
        buffers.get(b.index()).map(Vec::as_slice)
    })
    .ok_or("inverse bind matrices that cannot be read")?
    .map(|m| Mat4::from_cols_array_2d(&m))
    .collect();
    if inverse.len() < joints.len() {
        return Err(format!(
            "{} inverse bind matrices for {} joints",
            inverse.len(),
            joints.len()
        ));
    }
    Ok(joints.iter().zip(&inverse).map(|(j, i)| *j * *i).collect())
}

/// The skinning matrix of each of a primitive's `count` vertices: the sum of its
/// joints' `matrices` weighted by its weights (`JOINTS_n`/`WEIGHTS_n`, every set),
/// the weights scaled to sum to 1 as three.js does. A vertex of no weight keeps
/// `fallback`.
///
/// # Errors
/// A message when the primitive has no joints and weights, or they cannot be read,
/// or name a joint the skin does not have.
pub(super) fn vertex_matrices(
    primitive: &gltf::Primitive<'_>,
    matrices: &[Mat4],
    count: usize,
    fallback: Mat4,
    buffers: &[Vec<u8>],
) -> Result<Vec<Mat4>, String> {
    let mut sums = vec![Mat4::ZERO; count];
    let mut totals = vec![0.0f32; count];
    let mut sets = 0;
    for set in 0.. {
        let joints = primitive.get(&gltf::Semantic::Joints(set));
        let weights = primitive.get(&gltf::Semantic::Weights(set));
        let (Some(joints), Some(weights)) = (joints, weights) else {
            break;
        };
        checked(&joints, &JOINTS, buffers)?;
        checked(&weights, &WEIGHTS, buffers)?;
        let get = |b: gltf::Buffer<'_>| buffers.get(b.index()).map(Vec::as_slice);
        let joints: Vec<[u16; 4]> = match joints.data_type() {
            gltf::accessor::DataType::U8 => gltf::accessor::Iter::<[u8; 4]>::new(joints, get)
                .map(|i| i.map(|j| j.map(u16::from)).collect()),
            _ => gltf::accessor::Iter::<[u16; 4]>::new(joints, get).map(Iterator::collect),
        }
        .ok_or("joints that cannot be read")?;
        let weights = read_floats::<4>(weights, buffers).ok_or("weights that cannot be read")?;
        if joints.len() != count || weights.len() != count {
            return Err(format!(
                "{} joints and {} weights for {count} vertices",
                joints.len(),
                weights.len()
            ));
        }
        for (v, (js, ws)) in joints.iter().zip(&weights).enumerate() {
            for (&j, &w) in js.iter().zip(ws) {
                if w == 0.0 {
                    continue;
                }
                let m = matrices
                    .get(usize::from(j))
                    .ok_or_else(|| format!("joint {j} of a skin of {} joints", matrices.len()))?;
                sums[v] += *m * w;
                totals[v] += w;
            }
        }
        sets += 1;
    }
    if sets == 0 {
        return Err("no JOINTS_0 and WEIGHTS_0".into());
    }
    Ok(sums
        .into_iter()
        .zip(totals)
        .map(|(m, total)| match total.is_finite() && total > 0.0 {
            true => m * (1.0 / total),
            false => fallback,
        })
        .collect())
}

/// Adds to `positions` and `normals` (when the targets have them) the primitive's
/// morph targets times `weights` (glTF's default pose). Targets past the weights,
/// or of weight 0, are not read.
///
/// # Errors
/// A message when a target with a weight cannot be read.
pub(super) fn morph(
    primitive: &gltf::Primitive<'_>,
    weights: &[f32],
    positions: &mut [Vec3],
    mut normals: Option<&mut [Vec3]>,
    buffers: &[Vec<u8>],
) -> Result<(), String> {
    for (target, &weight) in primitive.morph_targets().zip(weights) {
        if weight == 0.0 || !weight.is_finite() {
            continue;
        }
        let add =
            |accessor: Option<gltf::Accessor<'_>>, values: &mut [Vec3]| -> Result<(), String> {
                let Some(accessor) = accessor else {
                    return Ok(());
                };
                checked(&accessor, &TARGET, buffers)?;
                let deltas = read_floats::<3>(accessor, buffers)
                    .ok_or("a morph target that cannot be read")?;
                if deltas.len() != values.len() {
                    return Err(format!(
                        "a morph target of {} values for {} vertices",
                        deltas.len(),
                        values.len()
                    ));
                }
                for (v, d) in values.iter_mut().zip(deltas) {
                    *v += Vec3::from(d) * weight;
                }
                Ok(())
            };
        add(target.positions(), positions)?;
        if let Some(normals) = normals.as_deref_mut() {
            add(target.normals(), normals)?;
        }
    }
    Ok(())
}

/// The matrix that places normals under `m`: its linear part's inverse transpose.
pub(super) fn normal_matrix(m: &Mat4) -> Mat3 {
    Mat3::from_mat4(*m).inverse().transpose()
}
