//! A device's data buffer, laid out as its spec's `buffer:` section names it
//! ([`BufferInfo`]; the P series: manual 4.1.2 registers 0022-0024, 4.2.2 notes 3-5, 5.4 and
//! appendix 3): the lock flag is the register the lock command writes, the source's code
//! names are the registers buffered, the page's read count, valid count and values are named.
//!
//! Behaviour: while unlocked and the count N is non-zero, one value of the source's
//! register is buffered every sampling interval × sampling ratio (the ratio-th measurement,
//! appendix 3 (5): at ratio 10 every 10th), up to N (appendix 3 (1)). Locking freezes
//! what is buffered (appendix 3 (2)) and restarts the read-out. Every read that covers a
//! buffered-value register returns the next page: up to a page of values, the valid count of
//! this page and the total read so far, including this page (appendix 3 (3)-(4), 5.4 (5): 1000
//! values take 17 reads, the 17th with 40 valid; the manual leaves open whether the total
//! includes this page, [`crate::Quirks::buffer_read_count`] gives it before); values past the valid count read as the
//! value register's sentinel. A read of the two counts alone does not turn the page. Unlocking
//! clears the buffer and starts buffering anew; changing the count, the source, the
//! sampling interval or the ratio resets the buffer and the lock flag (4.2.2 note 5,
//! appendix 3 (5) note 1). Unlocked, the
//! counts read 0 and every value is invalid.

use optobus_device::{BufferInfo, DeviceInfo};

/// What a register of the page is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Role {
    /// Total values read since the lock.
    ReadCount,
    /// Valid values of the current page.
    ValidCount,
    /// The `n`th value of the page (0-based).
    Value(usize),
}

/// Where the buffer's registers are.
#[derive(Clone, Debug)]
pub(crate) struct BufferLayout {
    /// The lock flag register.
    pub(crate) lock: usize,
    /// The count register.
    pub(crate) count: usize,
    /// The source register, if any (else the first code's register is buffered).
    pub(crate) source: Option<usize>,
    /// The sampling interval register, if any (else 1 ms).
    pub(crate) interval: Option<usize>,
    /// The sampling ratio register, if any (else every value is buffered).
    pub(crate) ratio: Option<usize>,
    read_count: usize,
    valid_count: usize,
    values: Vec<usize>,
}

impl BufferLayout {
    /// The buffer of `device`, if its spec describes one whose names all resolve.
    pub(crate) fn find(device: &'static DeviceInfo) -> Option<Self> {
        let info: &BufferInfo = device.buffer?;
        let index = |name: &str| device.registers.iter().position(|r| r.name == name);
        let lock = index(device.command(info.lock)?.register)?;
        let values: Vec<usize> = device
            .members(info.values)
            .filter_map(|r| index(r.name))
            .collect();
        Some(Self {
            lock,
            count: index(info.count)?,
            source: info.source.and_then(index),
            interval: info.interval.and_then(index),
            ratio: info.ratio.and_then(index),
            read_count: index(info.read_count)?,
            valid_count: index(info.valid_count)?,
            values: (!values.is_empty()).then_some(values)?,
        })
    }

    /// What register `index` is in the page.
    pub(crate) fn role(&self, index: usize) -> Option<Role> {
        if index == self.read_count {
            Some(Role::ReadCount)
        } else if index == self.valid_count {
            Some(Role::ValidCount)
        } else {
            self.values
                .iter()
                .position(|&v| v == index)
                .map(Role::Value)
        }
    }

    /// Whether a write to `index` resets the buffer (4.2.2 note 5, appendix 3 (5) note 1).
    pub(crate) fn resets_on(&self, index: usize) -> bool {
        index == self.count || [self.source, self.interval, self.ratio].contains(&Some(index))
    }

    fn page_size(&self) -> u32 {
        u32::try_from(self.values.len()).unwrap_or(u32::MAX)
    }
}

/// A locked buffer being read out.
#[derive(Clone, Copy, Debug)]
struct Locked {
    /// Values buffered when it was locked.
    filled: u32,
    /// Values read out so far.
    read: u32,
    /// First value and valid count of the current page.
    page_start: u32,
    valid: u32,
    /// Time of the first value, and seconds between values.
    first: f64,
    period: f64,
    /// The register whose values were buffered.
    source: Option<usize>,
}

/// The buffer's state.
#[derive(Clone, Debug)]
pub(crate) struct Buffer {
    pub(crate) layout: BufferLayout,
    /// When buffering (re)started.
    started: f64,
    locked: Option<Locked>,
}

impl Buffer {
    pub(crate) fn new(layout: BufferLayout, t: f64) -> Self {
        Self {
            layout,
            started: t,
            locked: None,
        }
    }

    /// Locks the buffer at `t`: `capacity` values requested, one per `period` seconds of
    /// `source`'s reading.
    pub(crate) fn lock(&mut self, t: f64, capacity: u32, period: f64, source: Option<usize>) {
        let period = if period > 0.0 { period } else { 1e-3 };
        let elapsed = ((t - self.started) / period).floor().max(0.0);
        let filled = (elapsed.min(f64::from(u32::MAX)) as u32).min(capacity);
        self.locked = Some(Locked {
            filled,
            read: 0,
            page_start: 0,
            valid: 0,
            first: self.started + period,
            period,
            source,
        });
    }

    /// Clears the buffer and starts buffering anew.
    pub(crate) fn reset(&mut self, t: f64) {
        self.started = t;
        self.locked = None;
    }

    /// Turns the page: the next read-out of up to a page of values.
    pub(crate) fn turn_page(&mut self) {
        let size = self.layout.page_size();
        if let Some(locked) = &mut self.locked {
            locked.page_start = locked.read;
            locked.valid = locked.filled.saturating_sub(locked.read).min(size);
            locked.read += locked.valid;
        }
    }

    /// The read and valid counts as the registers show them.
    pub(crate) fn counts(&self) -> (u32, u32) {
        self.locked.map_or((0, 0), |l| (l.read, l.valid))
    }

    /// The register buffered and the time of the `slot`th value of the current page, if it
    /// is valid.
    pub(crate) fn sample(&self, slot: usize) -> Option<(Option<usize>, f64)> {
        let locked = self.locked?;
        let slot = u32::try_from(slot).ok()?;
        (slot < locked.valid).then(|| {
            let n = locked.page_start + slot;
            (locked.source, locked.first + f64::from(n) * locked.period)
        })
    }
}
