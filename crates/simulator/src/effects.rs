//! What a write sets off: commands and their effects, saving, restarting.
//!
//! A command fires when its register is written with its value (for repeat blocks, the copy
//! written names the copy whose targets it acts on: CCF channel 2's `position_zero` zeroes
//! channel 2's `distance_1`). After a command its register returns to an "idle" code if it has
//! one that no command uses (P series 0020 and CCS/CCF save and trigger-count reset "clear
//! their flag": they read 0 again); other command registers keep the value written (a run
//! state, a lock flag, a zero switch). A command with `busy_ms` is answered, then the device
//! ignores every request for that long (CCS/CCF 4.1.2: about 400 ms of flash writing during
//! which requests time out; P series soft reboot). A command whose spec says how the device
//! shows it finished (`done_when`: P series, CCS and CCF save "clear their flag when the flash
//! write is done") keeps the value written in its register until then: for its busy time, or
//! as long as [`Simulator::finish_time`](crate::Simulator::finish_time) says (the P series
//! manual gives no save time).
//!
//! Effects:
//! - `zero`: each target's current reading becomes its zero (reads about 0 right after);
//!   `clear_zero` removes the offset. Zero offsets are not saved (CCS 4.1.2 note).
//! - `reset`: targets restart: a statistic's window, a counter, a sampled value (0 until the
//!   next sample).
//! - `save`: the current settings are stored; a reboot or power cycle restores them.
//! - `reboot`: the saved settings come back, offsets and the buffer are cleared.
//! - `factory_reset`: factory values at once; on devices whose settings apply only after save
//!   and power cycle (LC-RS) they are stored too, so the next restart uses them with or
//!   without a save (table 1 "重启有效", 2.3 "保存后重启生效": both hold).
//! - `network_reset`: targets get their factory values (P series 4.1.2 note 2: IP
//!   192.168.0.10), not saved.
//! - `buffer_lock` / `buffer_unlock`: see [`crate::buffer`].

use std::time::Duration;

use optobus_device::{parse_duration, CommandInfo, Effect};
use tokio::time::Instant;

use crate::layout::{command_copy, stored_words};
use crate::model::Device;
use crate::names;

impl Device {
    /// Acts on a valid write of `raw` to register `index`, already stored.
    pub(crate) fn after_write(&mut self, index: usize, raw: u32, now: Instant) {
        let t = self.seconds(now);
        let Some(register) = self.register(index) else {
            return;
        };
        if let Some(buffer) = &mut self.buffer {
            if buffer.layout.resets_on(index) {
                buffer.reset(t);
                let lock = buffer.layout.lock;
                if let Some(lock_register) = self.info.registers.get(lock) {
                    self.words[lock] = stored_words(lock_register, 0);
                }
            }
        }
        if register.name == names::SLAVE_ADDRESS && !self.info.needs_save_and_power_cycle {
            // Settings apply at once: the next request must use the new address (the reply
            // to this one still comes from the old).
            if let Some(address) = u8::try_from(raw).ok().filter(|a| (1..=247).contains(a)) {
                self.address = address;
            }
        }
        let fired: Vec<(&'static CommandInfo, Option<String>)> = self
            .info
            .commands
            .iter()
            .filter(|command| command.value == raw)
            .filter_map(|command| Some((command, command_copy(command, register)?)))
            .collect();
        if fired.is_empty() {
            return;
        }
        let used: Vec<u32> = self
            .info
            .commands
            .iter()
            .filter(|command| command_copy(command, register).is_some())
            .map(|command| command.value)
            .collect();
        let busy = fired
            .iter()
            .map(|(command, _)| command.busy_ms)
            .max()
            .unwrap_or(0);
        let busy = Duration::from_millis(u64::from(busy));
        let done = fired.iter().find_map(|(command, _)| command.done_when);
        if let Some(done) = done {
            // The register shows the value written until the device has finished, then the
            // value the spec says it shows.
            let words = stored_words(register, done.value);
            let at = now.checked_add(self.finish_time.unwrap_or(busy));
            self.finishing.retain(|(i, ..)| *i != index);
            self.finishing.push((index, at, words));
            self.settle(now);
        } else if let Some(idle) = register
            .codes
            .iter()
            .map(|code| code.code)
            .filter(|code| !used.contains(code))
            .min()
        {
            self.words[index] = stored_words(register, idle);
        }
        for (command, prefix) in fired {
            self.run(command, prefix.as_deref(), t);
        }
        if !busy.is_zero() {
            self.busy_until = Some(now + busy);
        }
    }

    /// Registers of commands that have finished by `now` show the value that says so.
    pub(crate) fn settle(&mut self, now: Instant) {
        let words = &mut self.words;
        self.finishing.retain(|(index, at, done)| {
            if at.is_none_or(|at| at > now) {
                return true;
            }
            if let Some(slot) = words.get_mut(*index) {
                slot.clone_from(done);
            }
            false
        });
    }

    /// The registers `command` acts on, in the copy `prefix` names if it has them.
    fn targets(&self, command: &CommandInfo, prefix: Option<&str>) -> Vec<usize> {
        command
            .targets
            .iter()
            .filter_map(|name| {
                prefix
                    .and_then(|prefix| self.layout.find(&format!("{prefix}{name}")))
                    .or_else(|| self.layout.find(name))
            })
            .collect()
    }

    fn run(&mut self, command: &CommandInfo, prefix: Option<&str>, t: f64) {
        let targets = self.targets(command, prefix);
        let signals = |device: &Device, index: usize| -> Vec<usize> {
            device
                .signals
                .of_register(index)
                .map(<[usize]>::to_vec)
                .unwrap_or_default()
        };
        match command.effect {
            Effect::Zero => {
                for index in targets {
                    self.pinned[index] = false;
                    for id in signals(self, index) {
                        self.signals.zero(id, t);
                    }
                }
            }
            Effect::ClearZero => {
                for index in targets {
                    for id in signals(self, index) {
                        self.signals.clear_zero(id);
                    }
                }
            }
            Effect::Reset => {
                for index in targets {
                    for id in signals(self, index) {
                        self.signals.reset(id, t);
                    }
                }
            }
            Effect::Save => self.flash = self.words.clone(),
            Effect::Reboot => self.restart(t),
            Effect::FactoryReset => {
                for index in 0..self.words.len() {
                    if !self.pinned[index] {
                        self.words[index] = self.factory[index].clone();
                    }
                }
                if self.info.needs_save_and_power_cycle {
                    self.flash = self.factory.clone();
                } else if let Some(address) = self.configured_slave(&self.words) {
                    self.address = address;
                }
            }
            Effect::NetworkReset => {
                for index in targets {
                    self.words[index] = self.factory[index].clone();
                }
            }
            Effect::BufferLock => self.lock_buffer(t),
            Effect::BufferUnlock => {
                if let Some(buffer) = &mut self.buffer {
                    buffer.reset(t);
                }
            }
            Effect::None => {}
        }
    }

    /// Locks the buffer with the current report count, sampling interval, ratio and data type.
    fn lock_buffer(&mut self, t: f64) {
        let Some(buffer) = &self.buffer else {
            return;
        };
        let layout = buffer.layout.clone();
        let value = |index: usize| -> Option<u32> {
            Some(self.register(index)?.raw(self.words.get(index)?))
        };
        let code = |index: usize| {
            let raw = value(index)?;
            self.register(index)?.codes.iter().find(|c| c.code == raw)
        };
        let capacity = value(layout.count).unwrap_or(0);
        let interval = layout
            .interval
            .and_then(code)
            .and_then(|c| parse_duration(c.meaning))
            .unwrap_or(1e-3);
        let ratio = layout.ratio.and_then(value).unwrap_or(1).max(1);
        let period = interval * f64::from(ratio);
        let source = layout
            .source
            .and_then(|index| code(index).or_else(|| self.register(index)?.codes.first()))
            .and_then(|c| self.layout.find(c.name));
        if let Some(buffer) = &mut self.buffer {
            buffer.lock(t, capacity, period, source);
        }
    }

    /// Restarts from the saved settings (reboot, power cycle): unsaved changes, zero offsets,
    /// resets, half-written values and the buffer are gone; the saved slave address applies.
    pub(crate) fn restart(&mut self, t: f64) {
        for index in 0..self.words.len() {
            if !self.pinned[index] {
                self.words[index] = self.flash[index].clone();
            }
        }
        self.pending.iter_mut().for_each(|p| *p = None);
        self.signals.clear_all();
        if let Some(buffer) = &mut self.buffer {
            buffer.reset(t);
        }
        if let Some(address) = self.configured_slave(&self.flash) {
            self.address = address;
        }
    }
}
