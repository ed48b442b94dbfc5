//! What a write does to the slave address a device answers at.

use optobus_device::{CommandInfo, DeviceInfo, Effect, RegisterInfo};

/// A write's change of the device's slave address.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AddressChange {
    /// The device answers at this address from the next request on: follow it with
    /// [`Core::set_slave`](crate::Core::set_slave).
    Now(u8),
    /// The device answers at `address` only once it is saved and the device power-cycled;
    /// until then at the old one.
    AfterSaveAndPowerCycle {
        /// The new address.
        address: u8,
        /// The command that saves, where the spec has one.
        save: Option<&'static CommandInfo>,
    },
}

/// What writing `words` to `register` of `device` does to its slave address: `None` for
/// every register but the device's own slave-address register (and for a value that is no
/// address; the spec's range keeps it within 1 to 247, which the checker demands).
pub fn address_change(
    device: &'static DeviceInfo,
    register: &RegisterInfo,
    words: &[u16],
) -> Option<AddressChange> {
    let own = device.slave_address_register()?;
    if own.name != register.name {
        return None;
    }
    let address = u8::try_from(register.raw(words)).ok()?;
    if !device.needs_save_and_power_cycle {
        return Some(AddressChange::Now(address));
    }
    let save = device.commands.iter().find(|c| c.effect == Effect::Save);
    Some(AddressChange::AfterSaveAndPowerCycle { address, save })
}
