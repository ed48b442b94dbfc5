//! The fault table: for each fault kind and each of our clients (RTU, Modbus TCP), 10,000
//! reads of registers holding known, distinct values, with the fault in 10 % of the replies.
//! Prints correct reads, typed errors by kind, wrong values (must be 0) and the share of
//! faults after which the next transaction was right (target >= 0.99).
//!
//! Runs in tokio's paused clock (everything is in memory), so timeouts and late replies cost
//! no wall time. Run with `cargo bench -p optobus-tests --bench faults`.

use optobus_tests::fault_run::{self, Client};

const TRANSACTIONS: usize = 10_000;
const PROBABILITY: f64 = 0.1;

fn main() {
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .start_paused(true)
        .build()
        .expect("runtime");
    println!(
        "{:<4} {:<12} {:>7} {:>8} {:>7} {:>6} {:>9}  typed errors",
        "link", "fault", "faults", "correct", "wrong", "untyped", "recovery"
    );
    let mut worst = 1.0f64;
    let mut wrong = 0;
    for client in [Client::Rtu, Client::Tcp] {
        for kind in fault_run::kinds(client) {
            let report =
                runtime.block_on(fault_run::run(kind, client, TRANSACTIONS, PROBABILITY, 7));
            let errors: Vec<String> = report
                .errors
                .iter()
                .map(|(kind, n)| format!("{kind} {n}"))
                .collect();
            println!(
                "{:<4} {:<12} {:>7} {:>8} {:>7} {:>6} {:>9.4}  {}",
                client.to_string(),
                kind.name(),
                report.injected,
                report.correct,
                report.wrong,
                report.untyped,
                report.recovery_rate(),
                errors.join(", ")
            );
            worst = worst.min(report.recovery_rate());
            wrong += report.wrong;
        }
    }
    println!(
        "wrong values in all runs: {wrong} (target 0); lowest recovery: {worst:.4} (target >= 0.99)"
    );
}
