//! The request handler of the converter's own objects ([`VendorObjects`]): the serial link and
//! settings objects (`objects.rs`), the configuration object (`config_object.rs`), the Parameter
//! object (`parameters.rs`), the serial-line analyzer (`analyzer_object.rs`) and the Modbus unit
//! health object (`units_object.rs`), each class sent to the file that serves it, and any other class
//! to the application's object ([`super::ApplicationObject`]: the update object). The node calls it for every class the DeviceNet core does not serve
//! itself.

use super::analyzer_object::{self, ANALYZER_CLASS};
use super::config_object::{ConfigObject, CONFIG_CLASS};
use super::objects::{
    AttributeType, LinkAttribute, SettingsAttribute, SettingsValues, SERIAL_LINK_CLASS, SETTINGS_CLASS,
};
use super::parameters::{self, PARAMETER_CLASS};
use super::units_object::{self, UNITS_CLASS};
use super::InputAssembly;
use crate::serial::trace::Trace;
use crate::serial::Profile;
use devicenet::explicit::{Request, ServiceCode};
use devicenet::slave::{ObjectHandler, Reply, ServiceError};
use devicenet::Instant;

/// The vendor objects' request handler, borrowing the serial side while the node serves a
/// request.
pub(super) struct VendorObjects<'a> {
    /// The running profile.
    pub(super) profile: &'a Profile,
    /// The produced assembly.
    pub(super) input: InputAssembly,
    /// The configuration object.
    pub(super) config: &'a mut ConfigObject,
    /// Whether an I/O (poll) connection is established.
    pub(super) io_established: bool,
    /// The serial-line analyzer's ring.
    pub(super) trace: &'a mut Trace,
    /// When the request arrived (the unit table's ages).
    pub(super) now: Instant,
    /// The application's object, asked for every class not ours ([`super::ApplicationObject`]).
    pub(super) extra: Option<&'a mut dyn super::ApplicationObject>,
}

impl VendorObjects<'_> {
    /// Get_Attribute_Single of instance attribute `id` of `class` (one of ours).
    fn get(&self, class: u16, id: u8, reply: &mut Reply<'_>) -> Result<(), ServiceError> {
        // `let ... else` rather than `ok_or(..)?`: 12 bytes less in the firmware.
        let (data_type, value) = if class == SERIAL_LINK_CLASS {
            let Some(a) = LinkAttribute::from_id(id) else {
                return Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED);
            };
            (a.data_type(), a.read(self.profile.counts(), &self.profile.status()))
        } else {
            let Some(a) = SettingsAttribute::from_id(id) else {
                return Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED);
            };
            (a.data_type(), a.read(&SettingsValues::of_profile(self.profile, self.input)))
        };
        match data_type {
            AttributeType::Udint => reply.u32(value),
            // One-byte types: the value fits by construction of `read` (tested).
            AttributeType::Usint | AttributeType::Byte => reply.u8(value as u8),
        }
    }
}

impl ObjectHandler for VendorObjects<'_> {
    fn handle(&mut self, req: &Request<'_>, reply: &mut Reply<'_>) -> Option<Result<(), ServiceError>> {
        let link = match req.class {
            SERIAL_LINK_CLASS => true,
            SETTINGS_CLASS => false,
            CONFIG_CLASS => return Some(self.config.handle(req, reply, self.io_established)),
            PARAMETER_CLASS => return Some(parameters::handle(self.config, req, reply, self.io_established)),
            ANALYZER_CLASS => return Some(analyzer_object::handle(self.trace, req, reply)),
            UNITS_CLASS => return Some(units_object::handle(self.profile, self.now, req, reply)),
            _ => return self.extra.as_mut()?.handle(req, reply, self.io_established, self.now),
        };
        let known = |id| {
            if link {
                LinkAttribute::from_id(id).is_some()
            } else {
                SettingsAttribute::from_id(id).is_some()
            }
        };
        // Class instance 0 is the node's (`class_revision`).
        Some(match (req.instance, req.service, req.data) {
            (1, ServiceCode::GetAttributeSingle, &[attr]) => self.get(req.class, attr, reply),
            (1, ServiceCode::GetAttributeSingle, data) => Err(ServiceError::wrong_length(data, 1)),
            (1, ServiceCode::SetAttributeSingle, &[attr, ..]) => Err(if known(attr) {
                ServiceError::ATTRIBUTE_NOT_SETTABLE
            } else {
                ServiceError::ATTRIBUTE_NOT_SUPPORTED
            }),
            (1, ServiceCode::SetAttributeSingle, []) => Err(ServiceError::NOT_ENOUGH_DATA),
            (1, _, _) => Err(ServiceError::SERVICE_NOT_SUPPORTED),
            _ => Err(ServiceError::OBJECT_DOES_NOT_EXIST),
        })
    }

    /// The serial link, settings, configuration, analyzer and unit health objects serve their
    /// revision, 1, and nothing else at class instance 0: the node answers there.
    fn class_revision(&self, class: u16) -> Option<u16> {
        if matches!(class, SERIAL_LINK_CLASS | SETTINGS_CLASS | CONFIG_CLASS | ANALYZER_CLASS | UNITS_CLASS) {
            return Some(1);
        }
        self.extra.as_ref()?.class_revision(class)
    }
}
