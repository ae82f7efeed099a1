//! Finding dynamically indexed descriptor-array accesses: an `OpAccessChain` whose base is a
//! descriptor variable (decorated `DescriptorSet`) of array type and whose first index is not a
//! constant. Shared by `nonuniform` and `pin-index`; [`find_all`] (constant indices too) by the
//! `index_bounds` instrumentation.
use super::edit::{self, id_operand};
use rspirv::dr::Module;
use rspirv::spirv::{Op, StorageClass, Word};

pub struct Access {
    pub func: usize,
    pub block: usize,
    pub inst: usize,
    pub chain: Word,
    pub var: Word,
    pub index: Word,
    pub storage: StorageClass,
    /// Element type of the array.
    pub element: Word,
}

pub fn find(m: &Module) -> Vec<Access> {
    accesses(m, true)
}

/// Every descriptor-array access, its index constant or not.
pub fn find_all(m: &Module) -> Vec<Access> {
    accesses(m, false)
}

fn accesses(m: &Module, dynamic_only: bool) -> Vec<Access> {
    let vars = edit::descriptor_variables(m);
    let mut out = Vec::new();
    for (fi, f) in m.functions.iter().enumerate() {
        for (bi, b) in f.blocks.iter().enumerate() {
            for (ii, i) in b.instructions.iter().enumerate() {
                if !matches!(i.class.opcode, Op::AccessChain | Op::InBoundsAccessChain) {
                    continue;
                }
                let (Some(base), Some(index), Some(chain)) =
                    (id_operand(i, 0), id_operand(i, 1), i.result_id)
                else {
                    continue;
                };
                if !vars.contains(&base) || (dynamic_only && edit::is_constant(m, index)) {
                    continue;
                }
                let Some(var) = edit::def(m, base) else {
                    continue;
                };
                let Some((storage, pointee)) =
                    var.result_type.and_then(|t| edit::pointer_info(m, t))
                else {
                    continue;
                };
                let Some(arr) = edit::def(m, pointee) else {
                    continue;
                };
                if !matches!(arr.class.opcode, Op::TypeArray | Op::TypeRuntimeArray) {
                    continue;
                }
                let element = id_operand(arr, 0).unwrap_or(0);
                out.push(Access {
                    func: fi,
                    block: bi,
                    inst: ii,
                    chain,
                    var: base,
                    index,
                    storage,
                    element,
                });
            }
        }
    }
    out
}
