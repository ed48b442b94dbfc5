//! Group read plans against the real device descriptions: the fewest requests, split at each
//! device's read limit, never across addresses a device may reject or registers whose read
//! changes the device or is undefined.

use optobus_device::{DeviceInfo, RegisterInfo, Table};
use optobus_driver::{plan_reads, ReadSpan};
use optobus_tests::generated::{ccf, ccs, lc_rs, p_series, rangefinder};

fn registers(device: &'static DeviceInfo, names: &[&str]) -> Vec<&'static RegisterInfo> {
    names
        .iter()
        .map(|n| {
            device
                .register(n)
                .unwrap_or_else(|| panic!("no register {n}"))
        })
        .collect()
}

fn span(table: Table, address: u16, count: u16) -> ReadSpan {
    ReadSpan {
        table,
        address,
        count,
    }
}

#[test]
fn p_series_measurements_are_one_read_of_ten_words() {
    let group = p_series::DEVICE.group("measurements").unwrap();
    let plan = plan_reads(
        &p_series::DEVICE,
        &registers(&p_series::DEVICE, group.registers),
    );
    assert_eq!(plan, [span(Table::Input, 0, 10)]);
}

#[test]
fn p_series_buffer_page_is_the_manuals_122_register_read() {
    let mut names = vec![
        "buffer_read_count".to_owned(),
        "buffer_valid_count".to_owned(),
    ];
    names.extend((1..=60).map(|n| format!("buffer_sample_{n}_buffered_value")));
    let names: Vec<&str> = names.iter().map(String::as_str).collect();
    let plan = plan_reads(&p_series::DEVICE, &registers(&p_series::DEVICE, &names));
    // 5.4: "01 04 00 10 00 7A".
    assert_eq!(plan, [span(Table::Input, 0x10, 0x7A)]);
}

#[test]
fn order_and_duplicates_do_not_matter() {
    let plan = plan_reads(
        &p_series::DEVICE,
        &registers(
            &p_series::DEVICE,
            &["thickness", "distance_1", "distance_1"],
        ),
    );
    assert_eq!(plan, [span(Table::Input, 0, 6)]);
}

#[test]
fn gaps_are_bridged_only_over_readable_registers() {
    // distance_1 (0-1) and statistic_2 (8-9): 2-7 are readable registers, one read.
    let plan = plan_reads(
        &p_series::DEVICE,
        &registers(&p_series::DEVICE, &["distance_1", "statistic_2"]),
    );
    assert_eq!(plan, [span(Table::Input, 0, 10)]);
    // temperature (140) and ip_address (150-153): the reserved 141-149 may be read (4.2.2
    // note 1), one read.
    let plan = plan_reads(
        &p_series::DEVICE,
        &registers(&p_series::DEVICE, &["temperature", "ip_address"]),
    );
    assert_eq!(plan, [span(Table::Input, 140, 14)]);
    // buffer_valid_count (17) and temperature (140): never over the buffer pages between.
    let plan = plan_reads(
        &p_series::DEVICE,
        &registers(&p_series::DEVICE, &["buffer_valid_count", "temperature"]),
    );
    assert_eq!(
        plan,
        [span(Table::Input, 17, 1), span(Table::Input, 140, 1)]
    );
}

#[test]
fn gaps_are_never_bridged_over_action_registers() {
    // The P series with statistic_1_reset (11) made an action register: 10 and 12 apart.
    let mut copy = p_series::DEVICE.registers.to_vec();
    let reset = copy
        .iter_mut()
        .find(|r| r.name == "statistic_1_reset")
        .unwrap();
    reset.action = true;
    let device: &'static DeviceInfo = Box::leak(Box::new(DeviceInfo {
        registers: Box::leak(copy.into_boxed_slice()),
        ..p_series::DEVICE
    }));
    let names = ["statistic_1_config", "statistic_2_enabled"];
    let plan = plan_reads(device, &registers(device, &names));
    assert_eq!(
        plan,
        [span(Table::Holding, 10, 1), span(Table::Holding, 12, 1)]
    );
    // As the spec has it, one read.
    let plan = plan_reads(&p_series::DEVICE, &registers(&p_series::DEVICE, &names));
    assert_eq!(plan, [span(Table::Holding, 10, 3)]);
}

#[test]
fn ccs_and_ccf_holding_reads_pass_over_their_reserved_rows() {
    // CCS 4.1.1 note 1: position_zero (3) and sampling_interval (8) over the reserved 4-7.
    let plan = plan_reads(
        &ccs::DEVICE,
        &registers(&ccs::DEVICE, &["position_zero", "sampling_interval"]),
    );
    assert_eq!(plan, [span(Table::Holding, 3, 6)]);
    // CCF: channel 1's and channel 2's light sources (0, 8) over the reserved 4-7.
    let plan = plan_reads(
        &ccf::DEVICE,
        &registers(
            &ccf::DEVICE,
            &[
                "channel_1_light_source_enabled",
                "channel_2_light_source_enabled",
            ],
        ),
    );
    assert_eq!(plan, [span(Table::Holding, 0, 9)]);
}

#[test]
fn tables_are_read_separately() {
    let plan = plan_reads(
        &p_series::DEVICE,
        &registers(&p_series::DEVICE, &["laser_enabled", "distance_1"]),
    );
    assert_eq!(plan, [span(Table::Holding, 0, 1), span(Table::Input, 0, 2)]);
}

#[test]
fn lc_rs_reads_split_at_its_limit_of_eight_words() {
    assert_eq!(lc_rs::DEVICE.max_read_words, 8);
    let group = lc_rs::DEVICE.group("serial_settings").unwrap();
    let plan = plan_reads(&lc_rs::DEVICE, &registers(&lc_rs::DEVICE, group.registers));
    // 0083H-0087H: five words in one read, as the spec's group says.
    assert_eq!(plan, [span(Table::Holding, 0x83, 5)]);
    let plan = plan_reads(
        &lc_rs::DEVICE,
        &registers(&lc_rs::DEVICE, &["baud_rate", "work_mode", "factory_reset"]),
    );
    // 0083H-0089H would be 7 words but 0088H is undefined: two reads.
    assert_eq!(
        plan,
        [span(Table::Holding, 0x83, 5), span(Table::Holding, 0x89, 1)]
    );
    for request in &plan {
        assert!(request.count <= 8);
    }
}

#[test]
fn rangefinder_reads_one_field_per_request() {
    let group = rangefinder::DEVICE.group("status").unwrap();
    let mut members = registers(&rangefinder::DEVICE, group.registers);
    members.sort_by_key(|r| r.address);
    let plan = plan_reads(&rangefinder::DEVICE, &members);
    let expected: Vec<ReadSpan> = members
        .iter()
        .map(|r| span(r.table, r.address, r.words))
        .collect();
    assert_eq!(plan, expected);
}

#[test]
fn ccf_channel_groups_are_read_per_channel() {
    let names: Vec<String> = ["distance_1", "distance_2", "thickness"]
        .iter()
        .map(|n| format!("channel_3_{n}"))
        .collect();
    let names: Vec<&str> = names.iter().map(String::as_str).collect();
    let members = registers(&ccf::DEVICE, &names);
    let plan = plan_reads(&ccf::DEVICE, &members);
    assert_eq!(plan.len(), 1);
    assert_eq!(plan[0].address, members[0].address);
    assert_eq!(plan[0].count, 6);
}

/// Answers each read with its addresses as words, until the `fail_at`-th request (0-based),
/// which times out.
struct FailingAt {
    fail_at: usize,
    made: usize,
}

impl optobus_driver::Transport for FailingAt {
    async fn read_words(
        &mut self,
        _: u8,
        read: optobus_driver::transport::ReadRequest,
    ) -> Result<Vec<u16>, optobus_driver::transport::Error> {
        self.made += 1;
        if self.made - 1 == self.fail_at {
            return Err(optobus_driver::transport::Error::Timeout {
                after: std::time::Duration::from_millis(1),
            });
        }
        Ok((0..read.count).map(|i| read.address + i).collect())
    }

    async fn write(
        &mut self,
        _: u8,
        _: u16,
        _: optobus_driver::transport::WriteValue,
    ) -> Result<(), optobus_driver::transport::Error> {
        Ok(())
    }
}

#[tokio::test]
async fn a_group_read_that_fails_halfway_keeps_what_was_read_and_names_the_failed_request() {
    // A holding and an input register: two requests, the second of which times out.
    let holding = p_series::DEVICE
        .registers
        .iter()
        .find(|r| r.table == Table::Holding && r.readable() && r.read_is_repeatable())
        .unwrap();
    let input = p_series::DEVICE.register("distance_1").unwrap();
    let plan = plan_reads(&p_series::DEVICE, &[holding, input]);
    assert_eq!(plan.len(), 2);
    let transport = FailingAt {
        fail_at: 1,
        made: 0,
    };
    let mut core = optobus_driver::Core::new(transport, 1, &p_series::DEVICE).unwrap();
    let partial = core
        .read_group_partly(&[holding, input])
        .await
        .expect_err("the second request fails");
    assert!(partial.has(holding));
    assert!(!partial.has(input));
    assert_eq!(partial.failed, Some(plan[1]));
    assert!(matches!(
        partial.error,
        optobus_driver::Error::Transport(optobus_driver::transport::Error::Timeout { .. })
    ));
    // The holding register's words are those its request brought.
    let first: Vec<u16> = (0..holding.words).map(|i| plan[0].address + i).collect();
    let offset = usize::from(holding.address - plan[0].address);
    assert_eq!(
        partial.readings.words(holding),
        &first[offset..offset + usize::from(holding.words)]
    );
}
