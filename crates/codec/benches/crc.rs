//! CRC throughput against the `crc` crate's fastest table implementation (slice-by-16).
//!
//! Prints, for 8-byte, 256-byte and 64 KiB inputs, both throughputs and our ratio to theirs
//! (above 1.0: we are faster). Run with `cargo bench -p optobus-codec --bench crc`.

use std::hint::black_box;
use std::time::{Duration, Instant};

const THEIRS: crc::Crc<u16, crc::Table<16>> =
    crc::Crc::<u16, crc::Table<16>>::new(&crc::CRC_16_MODBUS);

/// Best-of-`ROUNDS` bytes per second of `f` over `data`: the best round is the one the noisy
/// shared machine disturbed least.
fn throughput(data: &[u8], f: impl Fn(&[u8]) -> u16) -> f64 {
    const ROUNDS: usize = 15;
    let budget = Duration::from_millis(60);
    // Calibrate a batch that takes about the round budget.
    let mut batch = 1u64;
    loop {
        let start = Instant::now();
        for _ in 0..batch {
            black_box(f(black_box(data)));
        }
        if start.elapsed() >= budget / 4 {
            break;
        }
        batch *= 2;
    }
    (0..ROUNDS)
        .map(|_| {
            let start = Instant::now();
            for _ in 0..batch {
                black_box(f(black_box(data)));
            }
            (data.len() as f64 * batch as f64) / start.elapsed().as_secs_f64()
        })
        .fold(0.0, f64::max)
}

fn main() {
    // `cargo test --benches` runs bench targets with `--bench`; only a real run measures.
    if std::env::args().any(|a| a == "--list") {
        return;
    }
    println!("CRC-16/MODBUS throughput, optobus-codec vs crc::Crc<u16, Table<16>>");
    println!(
        "{:>10}  {:>14}  {:>14}  {:>7}",
        "input", "ours MB/s", "crc MB/s", "ratio"
    );
    for (label, len) in [("8 B", 8usize), ("256 B", 256), ("64 KiB", 65_536)] {
        let data: Vec<u8> = (0..len)
            .map(|i| (i as u32).wrapping_mul(2_654_435_761) as u8)
            .collect();
        assert_eq!(optobus_codec::crc::crc16(&data), THEIRS.checksum(&data));
        let ours = throughput(&data, optobus_codec::crc::crc16);
        let theirs = throughput(&data, |d| THEIRS.checksum(d));
        println!(
            "{label:>10}  {:>14.1}  {:>14.1}  {:>7.2}",
            ours / 1e6,
            theirs / 1e6,
            ours / theirs
        );
    }
}
