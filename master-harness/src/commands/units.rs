//! `dnet-master units`: a Modbus gateway's unit table (vendor class 0x69,
//! `slave_fw::converter::units_object`), one Get_Attribute_Single per value over the explicit
//! connection, printed as a table (or `--json`).
//!
//! Instance 1 attribute 7 gives the number of units; then instance `n` attributes 1–6 give unit
//! `n`'s address, state, lost data, retries, exceptions and the time since its last answer. A
//! converter that is not a Modbus gateway answers 0x16 (object does not exist) for instance 1:
//! that is an error naming the request, as is any other error response or a reply of the wrong
//! length.

use crate::options::{parse_mac, GlobalOptions};
use crate::run::{DeviceRun, Outcome, Ran};
use clap::Args;
use devicenet::explicit::{Request, ServiceCode};
use devicenet::MacId;
use harness_common::console::Console;
use harness_common::error::HarnessError;
use master_core::client::{Port, ReplyBody};
use master_core::decode;
use master_core::error::MasterError;
use master_core::master::Master;
use serde::Serialize;
use serde_json::json;
use slave_fw::converter::units_object::{state_name, NEVER_ANSWERED, UNITS_CLASS};
use slave_fw::serial::modbus::{UnitState, UNIT_CAPACITY};
use std::io::Write;

/// What `units` was asked.
#[derive(Args, Clone, Debug)]
pub struct UnitsArgs {
    /// The converter's MAC ID.
    #[arg(long, value_parser = parse_mac)]
    pub mac: MacId,
}

/// One unit as read from the device.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct UnitLine {
    /// The unit address.
    pub unit: u8,
    /// `starting`, `ok`, `lost`, `exception`.
    pub state: &'static str,
    /// Transactions failed after all retries.
    pub lost_data: u32,
    /// Retries sent.
    pub retries: u32,
    /// Exception responses.
    pub exceptions: u32,
    /// Milliseconds since its last answer; `None` before the first.
    pub since_answer_ms: Option<u32>,
}

/// Runs `units`; returns the exit status.
pub fn execute(
    opts: &GlobalOptions,
    args: &UnitsArgs,
    out: &mut dyn Write,
    err: &mut dyn Write,
    console: &Console,
) -> Result<u8, HarnessError> {
    let slave = opts.slave_description()?;
    let run = DeviceRun::new(opts, Some(args.mac), slave.as_ref())?;
    run.run(out, err, console, |master, _, _| {
        let result = read_table(master, args.mac).map(|units| Outcome {
            text: table(args.mac, &units),
            json: json!({ "units": units }),
            code: 0,
        });
        Ran::from(result)
    })
}

/// Reads every row of the unit table.
pub fn read_table(master: &mut Master<'_, '_>, mac: MacId) -> Result<Vec<UnitLine>, HarnessError> {
    master.open_explicit(mac)?;
    let [count] = get::<1>(master, mac, 1, 7)?;
    let count = usize::from(count);
    if count > UNIT_CAPACITY {
        return Err(protocol(mac, 1, 7, format!("{count} units, at most {UNIT_CAPACITY}")));
    }
    let mut units = Vec::with_capacity(count);
    for instance in 1..=count as u16 {
        let [unit] = get::<1>(master, mac, instance, 1)?;
        let [state] = get::<1>(master, mac, instance, 2)?;
        let state = UnitState::from_code(state)
            .ok_or_else(|| protocol(mac, instance, 2, format!("state {state} is not 0..=3")))?;
        let lost_data = u32::from_le_bytes(get::<4>(master, mac, instance, 3)?);
        let retries = u32::from_le_bytes(get::<4>(master, mac, instance, 4)?);
        let exceptions = u32::from_le_bytes(get::<4>(master, mac, instance, 5)?);
        let since = u32::from_le_bytes(get::<4>(master, mac, instance, 6)?);
        units.push(UnitLine {
            unit,
            state: state_name(state),
            lost_data,
            retries,
            exceptions,
            since_answer_ms: (since != NEVER_ANSWERED).then_some(since),
        });
    }
    Ok(units)
}

/// The table as printed.
pub fn table(mac: MacId, units: &[UnitLine]) -> String {
    let mut text = format!(
        "MAC {mac}: {} Modbus units\nunit  state      lost data   retries  exceptions  last answer\n",
        units.len()
    );
    for u in units {
        let last = u.since_answer_ms.map_or_else(|| "never".to_string(), |ms| format!("{ms} ms ago"));
        text.push_str(&format!(
            "{:>4}  {:<9}  {:>9}  {:>8}  {:>10}  {last}\n",
            u.unit, u.state, u.lost_data, u.retries, u.exceptions
        ));
    }
    text
}

fn protocol(mac: MacId, instance: u16, attribute: u8, reason: String) -> HarnessError {
    let req = Request {
        service: ServiceCode::GetAttributeSingle,
        class: UNITS_CLASS,
        instance,
        data: &[attribute],
    };
    let what = format!("{} at MAC {mac}", decode::request_text(&req));
    MasterError::Protocol { what, reason }.into()
}

/// Get_Attribute_Single of `attribute` of instance `instance`, exactly `N` bytes; an error response
/// or another length is an error naming the request.
fn get<const N: usize>(
    master: &mut Master<'_, '_>,
    mac: MacId,
    instance: u16,
    attribute: u8,
) -> Result<[u8; N], HarnessError> {
    let data = [attribute];
    let req = Request { service: ServiceCode::GetAttributeSingle, class: UNITS_CLASS, instance, data: &data };
    let answer = master.request(mac, Port::Explicit, &req)?;
    match answer.reply.body {
        ReplyBody::Success(bytes) => <[u8; N]>::try_from(bytes.as_slice())
            .map_err(|_| protocol(mac, instance, attribute, format!("{} bytes, expected {N}", bytes.len()))),
        ReplyBody::Error { general, additional } => {
            let text = decode::error_text(general, additional);
            let what = decode::request_text(&req);
            Err(MasterError::ErrorResponse { what, mac: mac.as_raw(), general, additional, text }.into())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_table_has_one_line_per_unit() {
        let units = [
            UnitLine {
                unit: 1,
                state: "ok",
                lost_data: 0,
                retries: 0,
                exceptions: 0,
                since_answer_ms: Some(12),
            },
            UnitLine {
                unit: 2,
                state: "lost",
                lost_data: 3,
                retries: 6,
                exceptions: 1,
                since_answer_ms: None,
            },
        ];
        let text = table(MacId::new(5).unwrap(), &units);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 4, "{text}");
        assert_eq!(lines[0], "MAC 5: 2 Modbus units");
        assert_eq!(lines[2], "   1  ok                 0         0           0  12 ms ago");
        assert_eq!(lines[3], "   2  lost               3         6           1  never");
    }
}
