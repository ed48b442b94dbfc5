//! The data-buffer download, once for every device whose spec has a `buffer:` section
//! ([`BufferInfo`]): buffering is started with a source and a count; later the buffer is
//! locked, read out a page at a time, and unlocked.

use std::fmt;
use std::time::Duration;

use optobus_device::{
    parse_duration, BufferInfo, CommandInfo, DeviceInfo, GroupInfo, RegisterInfo,
};
use optobus_transport::Transport;

use crate::convert::{Decode, Encode};
use crate::core::Core;
use crate::error::Error;

/// How far a download has got, passed to the progress callback after every page.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DownloadProgress {
    /// Valid values received so far.
    pub received: usize,
    /// Values the buffer was set to report.
    pub expected: usize,
    /// Pages read so far.
    pub pages: usize,
}

/// When a buffer's values were taken: one every sampling interval × sampling ratio (P series
/// appendix 3 (5): at ratio 10 every 10th measurement is buffered).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BufferTiming {
    /// The sampling interval: the time between two measurements.
    pub interval: Duration,
    /// Measurements per buffered value (1 for a buffer without a ratio register).
    pub ratio: u32,
}

impl BufferTiming {
    /// The time between two buffered values, `interval × ratio`.
    pub fn period(&self) -> Duration {
        self.interval.saturating_mul(self.ratio)
    }

    /// The time of value `index` (0 the oldest) after the oldest.
    pub fn time_of(&self, index: usize) -> Duration {
        let index = u32::try_from(index).unwrap_or(u32::MAX);
        self.period().saturating_mul(index)
    }
}

/// A buffer's items, looked up in the device description.
struct Parts {
    info: &'static BufferInfo,
    count: &'static RegisterInfo,
    lock: (&'static CommandInfo, &'static RegisterInfo),
    unlock: (&'static CommandInfo, &'static RegisterInfo),
    page: &'static GroupInfo,
    read_count: &'static RegisterInfo,
    valid_count: &'static RegisterInfo,
    /// Every copy of the values register, in page order.
    values: Vec<&'static RegisterInfo>,
}

/// What a page's read count counts. The manual (P series appendix 3 (3)) says the count of
/// values read since the lock reaches the total once all are read, but not whether a reply's
/// count already includes that reply's own page: a download decides from the first page with
/// values and holds the device to that reading for the rest.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum ReadCount {
    /// The values handed out so far, this page included.
    IncludingPage,
    /// The values handed out before this page.
    BeforePage,
}

impl ReadCount {
    /// The reading a page's `reported` count agrees with, given the values handed out
    /// `before` the page and `after` it; `reading` is what earlier pages decided (`None`
    /// while no page told the two apart). A count that fits neither, or contradicts the
    /// reading decided before, is [`Error::OutOfStep`]: a page was lost, or the device is
    /// not counting as it did.
    fn check(
        reading: Option<Self>,
        before: u64,
        after: u64,
        reported: u64,
    ) -> Result<Option<Self>, Error> {
        let fits = |reading: Self| match reading {
            Self::IncludingPage => reported == after,
            Self::BeforePage => reported == before,
        };
        let decided = match reading {
            Some(reading) => fits(reading).then_some(Some(reading)),
            // A page without values fits both readings and decides nothing.
            None if before == after => fits(Self::IncludingPage).then_some(None),
            None => [Self::IncludingPage, Self::BeforePage]
                .into_iter()
                .find(|&r| fits(r))
                .map(Some),
        };
        decided.ok_or(Error::OutOfStep {
            what: "the buffer download",
            received: match reading {
                Some(Self::BeforePage) => before,
                _ => after,
            },
            reported,
        })
    }
}

/// Refused: `device` describes no buffer, or one naming items it lacks.
fn no_buffer(name: &'static str) -> Error {
    Error::NotAllowed {
        register: name,
        what: "used as a data buffer (the device description has no such buffer)",
    }
}

impl Parts {
    fn of(device: &'static DeviceInfo) -> Result<Self, Error> {
        let info = device.buffer.ok_or_else(|| no_buffer(""))?;
        let register = |name: &'static str| device.register(name).ok_or_else(|| no_buffer(name));
        let command = |name: &'static str| {
            let command = device.command(name).ok_or_else(|| no_buffer(name))?;
            Ok::<_, Error>((command, register(command.register)?))
        };
        let values: Vec<_> = device.members(info.values).collect();
        if values.is_empty() {
            return Err(no_buffer(info.values));
        }
        Ok(Self {
            info,
            count: register(info.count)?,
            lock: command(info.lock)?,
            unlock: command(info.unlock)?,
            page: device
                .group(info.page)
                .ok_or_else(|| no_buffer(info.page))?,
            read_count: register(info.read_count)?,
            valid_count: register(info.valid_count)?,
            values,
        })
    }

    /// Refuses a count above the values that may be read out.
    fn check_count(&self, count: u32) -> Result<(), Error> {
        if count > self.info.most {
            return Err(Error::OutOfRange {
                register: self.count.name,
                raw: i64::from(count),
                min: 0,
                max: i64::from(self.info.most),
                scale: None,
                unit: None,
            });
        }
        Ok(())
    }
}

impl<T: Transport> Core<T> {
    /// The device's data buffer, if its spec describes one.
    pub fn buffer(&self) -> Option<&'static BufferInfo> {
        self.device().buffer
    }

    /// Reads when the buffer takes its values: the sampling interval register's code (its
    /// meaning is the duration) and the ratio register, where the buffer names them (`None`
    /// for a buffer that names no interval). An interval code the spec does not define, or a
    /// ratio of 0, is [`Error::UndefinedCode`] / [`Error::OutOfRange`]: no time axis is
    /// better than a wrong one.
    pub async fn read_buffer_timing(&mut self) -> Result<Option<BufferTiming>, Error> {
        let device = self.device();
        let info = device.buffer.ok_or_else(|| no_buffer(""))?;
        let Some(name) = info.interval else {
            return Ok(None);
        };
        let register = device.register(name).ok_or_else(|| no_buffer(name))?;
        let code = register.raw(&self.read_words(register).await?);
        let seconds = register
            .codes
            .iter()
            .find(|c| c.code == code)
            .and_then(|c| parse_duration(c.meaning))
            .ok_or(Error::UndefinedCode {
                register: register.name,
                field: None,
                code,
            })?;
        // Code meanings are written to the nanosecond at most (`6.25us`).
        let interval = Duration::from_nanos((seconds * 1e9).round() as u64);
        let ratio = match info.ratio {
            None => 1,
            Some(name) => {
                let register = device.register(name).ok_or_else(|| no_buffer(name))?;
                match register.raw(&self.read_words(register).await?) {
                    0 => {
                        return Err(Error::OutOfRange {
                            register: register.name,
                            raw: 0,
                            min: 1,
                            max: i64::from(u32::MAX),
                            scale: None,
                            unit: register.unit,
                        })
                    }
                    ratio => ratio,
                }
            }
        };
        Ok(Some(BufferTiming { interval, ratio }))
    }

    /// Starts buffering `count` values of `source` (writes the source register, if the
    /// buffer has one, and the count, then unlocks): 0 turns buffering off. A count above
    /// the buffer's `most` is refused with [`Error::OutOfRange`], and every value is checked,
    /// before anything is sent.
    pub async fn start_buffering(
        &mut self,
        source: Option<&dyn Encode>,
        count: u32,
    ) -> Result<(), Error> {
        let parts = Parts::of(self.device())?;
        parts.check_count(count)?;
        let source = match (parts.info.source, source) {
            (Some(name), Some(source)) => {
                let register = self
                    .device()
                    .register(name)
                    .ok_or_else(|| no_buffer(name))?;
                Some((register, source.encode(register)?))
            }
            _ => None,
        };
        let count_words = count.encode(parts.count)?;
        if let Some((register, words)) = source {
            self.write_words(register, &words).await?;
        }
        self.write_words(parts.count, &count_words).await?;
        let (command, register) = parts.unlock;
        self.run(command, register).await
    }

    /// Reads the buffer out: locks it, reads pages until the count it was set to is reached
    /// or a page carries no valid value, and unlocks it again, also when a read fails. Values
    /// come oldest first, each decoded as `V` (`Option<_>` gives `None` for a value the
    /// device marks invalid); values past a page's valid count are ignored.
    ///
    /// Reading a page turns it, so a page read is never retried, and at most the pages the
    /// count needs are read. Every page's read count (the device's count of values handed
    /// out since the lock) is checked against the values received: a page lost on the way
    /// fails the download with [`Error::OutOfStep`] instead of returning fewer values. The
    /// manual leaves open whether that count includes the page it comes with; the first page
    /// with values decides, and a later page counting the other way is [`Error::OutOfStep`].
    pub async fn download_buffer<V: Decode + fmt::Debug>(
        &mut self,
        mut progress: impl FnMut(DownloadProgress),
    ) -> Result<Vec<V>, Error> {
        let parts = Parts::of(self.device())?;
        let count: u32 = self.read(parts.count).await?;
        let expected = usize::try_from(count.min(parts.info.most)).unwrap_or(usize::MAX);
        let (command, register) = parts.lock;
        self.run(command, register).await?;
        let result = self.read_pages(&parts, expected, &mut progress).await;
        let (command, register) = parts.unlock;
        let unlocked = self.run(command, register).await;
        let values = result?;
        unlocked?;
        Ok(values)
    }

    async fn read_pages<V: Decode + fmt::Debug>(
        &mut self,
        parts: &Parts,
        expected: usize,
        progress: &mut impl FnMut(DownloadProgress),
    ) -> Result<Vec<V>, Error> {
        let page_values = parts.values.len();
        let mut values = Vec::with_capacity(expected);
        // Values the device handed out in the pages we received.
        let mut handed_out = 0u64;
        let mut reading = None;
        // Each page must be read whole, or values are lost; a device that keeps reporting
        // values is stopped after the pages `expected` needs.
        let max_pages = expected.div_ceil(page_values);
        for pages in 1..=max_pages {
            let page = self.read_declared_group(parts.page).await?;
            let read_count: u32 = page.get(parts.read_count);
            let valid_count: u32 = page.get(parts.valid_count);
            let valid_in_page = usize::try_from(valid_count)
                .unwrap_or(usize::MAX)
                .min(page_values);
            let before = handed_out;
            handed_out += valid_in_page as u64;
            reading = ReadCount::check(reading, before, handed_out, u64::from(read_count))?;
            let valid = valid_in_page.min(expected - values.len());
            values.extend(parts.values[..valid].iter().map(|r| page.get::<V>(r)));
            progress(DownloadProgress {
                received: values.len(),
                expected,
                pages,
            });
            if valid == 0 || values.len() >= expected {
                break;
            }
        }
        Ok(values)
    }
}
