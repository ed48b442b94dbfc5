//! `e2e::<family>`, for every spec in `specs/`: the spec's runtime description drives both the
//! simulator and the driver core the generated methods call, over our RTU client and real
//! bytes. Every readable register and every group is read and compared word for word with
//! what the simulator holds; then every setting is written with valid values and read back.

use optobus_device::{DeviceInfo, RegisterInfo};
use optobus_driver::{Core, Transport};
use optobus_simulator::Simulator;
use optobus_tests::e2e::{read_whole, simulated, write_every_register};
use optobus_tests::specs;

/// The words the simulator shows for `register` now.
fn held(sim: &Simulator, register: &RegisterInfo) -> Vec<u16> {
    sim.register(register.name)
        .unwrap_or_else(|| panic!("the simulator has no `{}`", register.name))
        .words
}

/// Reads each readable register alone; returns how many were compared with the simulator.
async fn read_registers<T: Transport>(sim: &Simulator, core: &mut Core<T>) -> usize {
    let device = core.device();
    let mut compared = 0;
    for register in device.readable_registers() {
        let before = held(sim, register);
        let words = read_whole(core, register).await;
        // A read that turns a buffer page shows the page it turned away from.
        assert_eq!(words, before, "{}", register.name);
        compared += 1;
    }
    compared
}

/// Reads every group in its planned requests and compares each member with the simulator.
async fn read_groups<T: Transport>(sim: &Simulator, core: &mut Core<T>) -> usize {
    let device: &'static DeviceInfo = core.device();
    let mut compared = 0;
    for group in device.groups {
        let members: Vec<&'static RegisterInfo> = group
            .registers
            .iter()
            .flat_map(|name| device.members(name))
            .collect();
        assert!(!members.is_empty(), "group {} has no member", group.name);
        let before: Vec<Vec<u16>> = members.iter().map(|r| held(sim, r)).collect();
        let readings = core
            .read_declared_group(group)
            .await
            .unwrap_or_else(|e| panic!("group {}: {e}", group.name));
        for (register, before) in members.iter().zip(before) {
            assert_eq!(
                readings.words(register),
                before.as_slice(),
                "group {}: {}",
                group.name,
                register.name
            );
            compared += 1;
        }
    }
    compared
}

async fn every_register_and_group(family: &str) {
    let device = specs::describe(family);
    let (sim, client) = simulated(device);
    let mut core = Core::with_default_slave(client, device);
    let registers = read_registers(&sim, &mut core).await;
    assert!(registers > 0, "{family}: nothing readable");
    read_groups(&sim, &mut core).await;
    write_every_register(&mut core).await;
    // The sweep's writes are what the simulator holds now.
    read_registers(&sim, &mut core).await;
}

optobus_tests::family_cases!(e2e, async every_register_and_group);
