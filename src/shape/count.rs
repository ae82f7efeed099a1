//! Function-body instruction counts: `OpFunction` through `OpFunctionEnd`, every parameter,
//! label and instruction between, over every function — what `reduce` holds its result to
//! (issue 25: at most a third of the original's).
use rspirv::dr::Module;

/// The instructions of every function of `m`, `OpFunction` and `OpFunctionEnd` included.
pub fn function_body(m: &Module) -> usize {
    m.functions
        .iter()
        .map(|f| {
            let blocks: usize = f.blocks.iter().map(|b| 1 + b.instructions.len()).sum();
            2 + f.parameters.len() + blocks
        })
        .sum()
}

/// [`function_body`] of SPIR-V words (`None`: not a module rspirv loads).
pub fn function_body_of(words: &[u32]) -> Option<usize> {
    let m = rspirv::dr::load_words(words).ok()?;
    Some(function_body(&m))
}
