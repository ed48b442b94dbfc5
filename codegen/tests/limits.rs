//! Hostile spec files: each is answered at once with a located error or a result, never by
//! exhausting the machine. How fast is measured by `benches/check.rs`, not here.

#[path = "support/large_spec.rs"]
mod large_spec;

#[test]
fn a_spec_of_100000_registers_checks() {
    let spec = large_spec::large_spec(100_000);
    let model = optobus_codegen::check_source("large.yaml", &spec)
        .unwrap_or_else(|rejected| panic!("{}", rejected.render()));
    assert_eq!(model.registers.len(), 100_000);
}
