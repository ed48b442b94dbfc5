//! What a driver learns about one device from its answers, so that a request the device
//! refused is not made again: kept per device, by a [`crate::Core`] for its device, and by
//! anything else that talks to several (a bus keeps one per device).

use optobus_codec::ExceptionCode;
use optobus_device::{DeviceInfo, RegisterInfo};

use crate::error::Error;
use crate::plan::{plan_reads_bridging, Bridging, ReadSpan};

/// What one device has shown about itself beyond its spec.
///
/// Reserved ranges: the specs mark reserved ranges `readable` where the manual counts them
/// in a table whose reads it allows and says nothing against reading them (an inference, see
/// `specs/README.md`), and read plans bridge them. A device (or a gateway in front of it)
/// that answers such a read with exception 02 (illegal data address) is read with plans that
/// do not cross reserved ranges from then on: [`DeviceMemory::fallback`] gives the requests
/// to make instead of the refused one and remembers it, [`DeviceMemory::plan_reads`] plans
/// accordingly.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DeviceMemory {
    bridging: Bridging,
}

impl DeviceMemory {
    /// What read plans for this device may pass over.
    pub fn bridging(&self) -> Bridging {
        self.bridging
    }

    /// Whether the device refused a read crossing a reserved range.
    pub fn refuses_reserved_reads(&self) -> bool {
        self.bridging == Bridging::RegistersOnly
    }

    /// The requests that read `registers` from this device (see [`crate::plan_reads`]).
    pub fn plan_reads(&self, device: &DeviceInfo, registers: &[&RegisterInfo]) -> Vec<ReadSpan> {
        plan_reads_bridging(device, registers, self.bridging)
    }

    /// After `span`, one request of a plan for `registers`, failed with `error`: the requests
    /// that read the registers of `registers` it holds without crossing a reserved range, when
    /// the device refused the span with exception 02 because it crossed one, which is
    /// remembered. `None` when the failure stands: any other error, a span that crosses no
    /// reserved range, or one whose read changes the device (never made twice).
    pub fn fallback(
        &mut self,
        device: &DeviceInfo,
        registers: &[&RegisterInfo],
        span: &ReadSpan,
        error: &Error,
    ) -> Option<Vec<ReadSpan>> {
        let refused = error.exception() == Some(ExceptionCode::ILLEGAL_DATA_ADDRESS);
        if !refused || !span.bridges_reserved(device) || !span.is_repeatable(device) {
            return None;
        }
        self.bridging = Bridging::RegistersOnly;
        let inside: Vec<&RegisterInfo> = registers
            .iter()
            .copied()
            .filter(|r| span.offset_of(r, device.addressing).is_some())
            .collect();
        Some(self.plan_reads(device, &inside))
    }
}
