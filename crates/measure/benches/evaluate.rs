//! Evaluation per value (issue 32: ≤ 2 µs), against its anchor in the same run: the same
//! arithmetic written by hand on the same exact decimals.
//!
//! Run with `cargo bench -p optobus-measure --bench evaluate`.

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, Criterion};
use optobus_codec::value::{Fixed, Scale};
use optobus_measure::{check, Decimal, Definition, InputInfo};

const MICRO_MM: Scale = Scale::Decimal { exponent: -6 };

fn evaluate(c: &mut Criterion) {
    let definitions = [Definition {
        name: "gap",
        expr: "20mm - top.distance_1 - bottom.distance_1",
        unit: Some("mm"),
    }];
    let plan = check(&definitions, |_, _| {
        Ok(InputInfo {
            unit: Some("mm"),
            scale: Some(MICRO_MM),
        })
    })
    .expect("a valid measurement");
    let inputs = [
        Some(Fixed::new(4_969_234, MICRO_MM)),
        Some(Fixed::new(4_969_136, MICRO_MM)),
    ];
    let mut group = c.benchmark_group("gap");
    group.bench_function("by hand (anchor)", |b| {
        b.iter(|| {
            let [top, bottom] =
                black_box(&inputs).map(|v| Decimal::from_fixed(v.unwrap(), -3).unwrap());
            let gap = Decimal::new(20, -3)
                .checked_sub(top)
                .unwrap()
                .checked_sub(bottom)
                .unwrap();
            Decimal::new(gap.mantissa(), gap.exponent() + 3).to_fixed(-6)
        })
    });
    group.bench_function("plan.evaluate", |b| {
        b.iter(|| plan.evaluate(black_box(&inputs)))
    });
    group.finish();
}

criterion_group!(benches, evaluate);
criterion_main!(benches);
