//! CRC-16/MODBUS throughput, ours against the `crc` crate's fastest table implementation
//! (slice-by-16), on criterion: 8-byte (an RTU request), 256-byte (a long reply) and 64 KiB
//! inputs. Both sides are called through the same kind of non-inlined function, so that
//! neither gains from being inlined into the benchmark loop (an 8-byte CRC inlined into a
//! constant-input loop measures the compiler, not the CRC).
//!
//!     cargo bench -p optobus-codec --bench crc

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};

const THEIRS: crc::Crc<u16, crc::Table<16>> =
    crc::Crc::<u16, crc::Table<16>>::new(&crc::CRC_16_MODBUS);

#[inline(never)]
fn ours(data: &[u8]) -> u16 {
    optobus_codec::crc::crc16(data)
}

#[inline(never)]
fn theirs(data: &[u8]) -> u16 {
    THEIRS.checksum(data)
}

fn crc16_modbus(c: &mut Criterion) {
    let mut group = c.benchmark_group("crc16_modbus");
    for len in [8usize, 256, 65_536] {
        let data: Vec<u8> = (0..len)
            .map(|i| (i as u32).wrapping_mul(2_654_435_761) as u8)
            .collect();
        assert_eq!(ours(&data), theirs(&data), "both compute CRC-16/MODBUS");
        group.throughput(Throughput::Bytes(len as u64));
        group.bench_with_input(BenchmarkId::new("optobus", len), &data, |b, data| {
            b.iter(|| ours(black_box(data)))
        });
        group.bench_with_input(BenchmarkId::new("crc", len), &data, |b, data| {
            b.iter(|| theirs(black_box(data)))
        });
    }
    group.finish();
}

criterion_group!(benches, crc16_modbus);
criterion_main!(benches);
