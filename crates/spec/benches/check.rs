//! How the checker grows with a spec's size: `check_source` (parse, read, lower, every rule) of
//! a generated spec of 1,000 registers (the anchor) and of 100,000. With every pass n log n the
//! second takes about a hundred times the first, well under a second (from 1 MiB on the parse
//! runs on a second thread, so on two cores the large spec gains a little more than the small).
//!
//!     cargo bench -p optobus-spec --bench check

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};

#[path = "../tests/support/large_spec.rs"]
mod large_spec;

fn check(c: &mut Criterion) {
    let mut group = c.benchmark_group("check");
    group.sample_size(10);
    for registers in [1_000, 100_000] {
        let spec = large_spec::large_spec(registers);
        group.bench_with_input(BenchmarkId::from_parameter(registers), &spec, |b, spec| {
            b.iter(|| optobus_spec::check_source("large.yaml", black_box(spec)).is_ok());
        });
    }
    group.finish();
}

criterion_group!(benches, check);
criterion_main!(benches);
