//! `dnet-master get` and `set`: Get_Attribute_Single and Set_Attribute_Single through the
//! device's explicit connection, the value decoded where the attribute is known.

use crate::options::{parse_mac, parse_u16, parse_u8, GlobalOptions, HexBytes};
use crate::run::{DeviceRun, Outcome};
use clap::Args;
use devicenet::explicit::ServiceCode;
use devicenet::MacId;
use harness_common::console::Console;
use harness_common::error::HarnessError;
use master_core::client::ReplyBody;
use master_core::decode;
use master_core::error::MasterError;
use master_core::master::Master;
use serde_json::json;
use std::io::Write;

/// What `get` was asked.
#[derive(Args, Clone, Debug)]
pub struct GetArgs {
    /// Device MAC ID.
    #[arg(value_parser = parse_mac)]
    pub mac: MacId,
    /// Class ID.
    #[arg(value_parser = parse_u16)]
    pub class: u16,
    /// Instance ID.
    #[arg(value_parser = parse_u16)]
    pub instance: u16,
    /// Attribute ID.
    #[arg(value_parser = parse_u8)]
    pub attribute: u8,
}

/// What `set` was asked.
#[derive(Args, Clone, Debug)]
pub struct SetArgs {
    /// Device MAC ID.
    #[arg(value_parser = parse_mac)]
    pub mac: MacId,
    /// Class ID.
    #[arg(value_parser = parse_u16)]
    pub class: u16,
    /// Instance ID.
    #[arg(value_parser = parse_u16)]
    pub instance: u16,
    /// Attribute ID.
    #[arg(value_parser = parse_u8)]
    pub attribute: u8,
    /// The value in hex.
    pub value: HexBytes,
}

/// Runs `get`; returns the exit status.
pub fn get(
    opts: &GlobalOptions,
    args: &GetArgs,
    out: &mut dyn Write,
    err: &mut dyn Write,
    console: &Console,
) -> Result<u8, HarnessError> {
    let slave = opts.slave_description()?;
    let run = DeviceRun::new(opts, Some(args.mac), slave.as_ref())?;
    run.run(out, err, console, |master, _, _| {
        request(master, args.mac, args.class, args.instance, args.attribute, None).into()
    })
}

/// Runs `set`; returns the exit status.
pub fn set(
    opts: &GlobalOptions,
    args: &SetArgs,
    out: &mut dyn Write,
    err: &mut dyn Write,
    console: &Console,
) -> Result<u8, HarnessError> {
    let slave = opts.slave_description()?;
    let run = DeviceRun::new(opts, Some(args.mac), slave.as_ref())?;
    run.run(out, err, console, |master, _, _| {
        request(master, args.mac, args.class, args.instance, args.attribute, Some(&args.value.0)).into()
    })
}

/// The request (a Set with `value`), its answer decoded; an error response fails the frame.
fn request(
    master: &mut Master<'_, '_>,
    mac: MacId,
    class_id: u16,
    instance: u16,
    attribute: u8,
    value: Option<&Vec<u8>>,
) -> Result<Outcome, HarnessError> {
    master.open_explicit(mac)?;
    let mut data = vec![attribute];
    let service = match value {
        Some(v) => {
            data.extend_from_slice(v);
            ServiceCode::SetAttributeSingle
        }
        None => ServiceCode::GetAttributeSingle,
    };
    let req = devicenet::explicit::Request { service, class: class_id, instance, data: &data };
    let what = decode::request_text(&req);
    let answer = master.request(mac, master_core::client::Port::Explicit, &req)?;
    let target = format!(
        "{} inst {instance} {}",
        decode::class_text(class_id),
        decode::attribute_text(class_id, instance, attribute)
    );
    let outcome = match answer.reply.body {
        ReplyBody::Success(bytes) => {
            let shown = if value.is_some() && bytes.is_empty() {
                "success".to_string()
            } else {
                decode::value_text(class_id, instance, attribute, &bytes)
            };
            let frag = if answer.reply.fragmented { " (fragmented response)" } else { "" };
            Outcome {
                text: if bytes.is_empty() {
                    format!("MAC {mac} {target}: {shown}{frag}")
                } else {
                    format!("MAC {mac} {target}: {shown}{frag}\nhex: {}", decode::hex(&bytes))
                },
                json: json!({ "request": what, "value": shown, "hex": decode::hex(&bytes).replace(' ', ""), "fragmented": answer.reply.fragmented }),
                code: 0,
            }
        }
        ReplyBody::Error { general, additional } => {
            let text = decode::error_text(general, additional);
            if let Some(i) = answer.record {
                let v = master.session.record(i).verdict.clone();
                master.session.set_verdict(i, v.with_failures(vec![format!("error response: {text}")]));
            }
            return Err(
                MasterError::ErrorResponse { what, mac: mac.as_raw(), general, additional, text }.into()
            );
        }
    };
    Ok(outcome)
}
