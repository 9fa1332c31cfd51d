//! The host builds its bind group layouts from `kernels::bindings` and dispatches the entry
//! points named in the integrator table; the SPIR-V module declares its own. Read the
//! compiled module and hold each to the other, so a binding or an entry point changed on
//! one side only fails here instead of as a driver error or a black image.
use std::collections::{BTreeMap, BTreeSet};

use kernels::bindings::{Binding, PRESENT, RESTIR, SCENE};
use runner::gpu::every_entry_point;
use runner::integrator::{Integrator, Kernel};
use runner::restir::RestirPass;

// SPIR-V opcodes and decorations used below (SPIR-V 1.5 specification, section 3).
const OP_ENTRY_POINT: u32 = 15;
const OP_DECORATE: u32 = 71;
const DECORATION_NON_WRITABLE: u32 = 24;
const DECORATION_BINDING: u32 = 33;
const DECORATION_DESCRIPTOR_SET: u32 = 34;
const HEADER_WORDS: usize = 5;

/// A literal string operand: its text and the words it takes.
fn string_operand(words: &[u32]) -> (String, usize) {
    let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
    let len = bytes.iter().position(|&b| b == 0).expect("nul-terminated");
    (String::from_utf8_lossy(&bytes[..len]).into(), len / 4 + 1)
}

#[derive(Default, Debug)]
struct Variable {
    set: Option<u32>,
    binding: Option<u32>,
    non_writable: bool,
}

/// Entry point name → the (set, binding, read-only) of the buffers its interface lists.
fn module_bindings() -> BTreeMap<String, BTreeSet<(u32, u32, bool)>> {
    let words = runner::gpu::spirv_words();
    assert_eq!(words[0], 0x0723_0203, "SPIR-V magic number");
    let mut vars: BTreeMap<u32, Variable> = BTreeMap::new();
    let mut entries: Vec<(String, Vec<u32>)> = Vec::new();
    let mut i = HEADER_WORDS;
    while i < words.len() {
        let (count, op) = ((words[i] >> 16) as usize, words[i] & 0xffff);
        let ins = &words[i..i + count];
        match op {
            OP_ENTRY_POINT => {
                let (name, used) = string_operand(&ins[3..]);
                entries.push((name, ins[3 + used..].to_vec()));
            }
            OP_DECORATE => {
                let v = vars.entry(ins[1]).or_default();
                match ins[2] {
                    DECORATION_DESCRIPTOR_SET => v.set = Some(ins[3]),
                    DECORATION_BINDING => v.binding = Some(ins[3]),
                    DECORATION_NON_WRITABLE => v.non_writable = true,
                    _ => {}
                }
            }
            _ => {}
        }
        i += count;
    }
    entries
        .into_iter()
        .map(|(name, interface)| {
            let buffers = interface
                .iter()
                .filter_map(|id| vars.get(id))
                .filter_map(|v| Some((v.set?, v.binding?, v.non_writable)))
                .collect();
            (name, buffers)
        })
        .collect()
}

fn table_set(tables: &[&[Binding]]) -> BTreeSet<(u32, u32, bool)> {
    tables
        .iter()
        .flat_map(|t| t.iter())
        .map(|b| (b.set, b.binding, b.read_only))
        .collect()
}

#[test]
fn the_module_declares_the_bindings_of_the_tables() {
    let module = module_bindings();
    let compute = table_set(&[&SCENE, &RESTIR]);
    let mut used = BTreeSet::new();
    for (name, buffers) in &module {
        let allowed = if name.starts_with("entry::present") {
            table_set(&[&PRESENT])
        } else {
            compute.clone()
        };
        // Every buffer an entry point uses is in its table, read-only exactly when the table
        // says so (a writable binding declared read-only on the host is a validation error;
        // the reverse hides a write).
        for b in buffers {
            assert!(
                allowed.contains(b),
                "{name} uses (set {}, binding {}, read-only {}), which the table does not declare",
                b.0,
                b.1,
                b.2
            );
        }
        if !name.starts_with("entry::present") {
            used.extend(buffers.iter().copied());
        }
    }
    // And every binding of the tables is used by some kernel (no stale table rows).
    assert_eq!(used, compute, "bindings the kernels use vs the tables");
    assert_eq!(
        module["entry::present_fs"],
        table_set(&[&PRESENT]),
        "present pass"
    );
}

#[test]
fn every_entry_point_the_host_dispatches_exists() {
    let module = module_bindings();
    let mut names: Vec<&str> = RestirPass::ENTRY_POINTS
        .iter()
        .flat_map(|p| [p.entry_point(false), p.entry_point(true)])
        .collect();
    // Image kernels in either workgroup size (AO's 16×56 on NVIDIA adapters).
    for kernel in Integrator::ALL.into_iter().flat_map(Integrator::kernels) {
        if let Kernel::Image { .. } = kernel {
            names.extend(every_entry_point(kernel).into_iter().map(|(name, _)| name));
        }
    }
    for name in names {
        assert!(
            module.contains_key(name),
            "{name} is not an entry point of the module: {:?}",
            module.keys().collect::<Vec<_>>()
        );
    }
    // ReSTIR passes bind set 1; image kernels only set 0 (their pipeline layout has one set).
    for kernel in Integrator::ALL.into_iter().flat_map(Integrator::kernels) {
        if let Kernel::Image { .. } = kernel {
            for (entry_point, _) in every_entry_point(kernel) {
                assert!(
                    module[entry_point].iter().all(|b| b.0 == 0),
                    "{entry_point} binds a set the image pipeline layout does not have"
                );
            }
        }
    }
}
