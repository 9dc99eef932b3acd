//! The Message Router (class 0x02): hands each explicit request to the object class it names,
//! and serves the class instance (the revision) of every core class, its own included.

use super::class_revision;
use crate::explicit::{Request, ServiceCode};
use crate::objects::class;
use crate::slave::{ObjectHandler, Reply, ServiceError, SlaveNode};
use crate::time::Instant;

impl SlaveNode {
    /// Routes `req` to the class it names; classes the core does not implement go to `objects`.
    // Out of line: inlined into `serve`, the two share one frame and the register shuffling
    // between them costs some 150 bytes of the firmware's flash.
    #[inline(never)]
    pub(in crate::slave) fn dispatch<H: ObjectHandler>(
        &mut self,
        req: &Request<'_>,
        reply: &mut Reply<'_>,
        now: Instant,
        objects: &mut H,
    ) -> Result<(), ServiceError> {
        let revision = match req.class {
            class::IDENTITY | class::MESSAGE_ROUTER | class::CONNECTION | class::ACKNOWLEDGE_HANDLER => 1,
            class::DEVICENET | class::ASSEMBLY => 2,
            // An application class that leaves its class instance to the node.
            class => match objects.class_revision(class) {
                Some(revision) if req.instance == 0 => revision,
                _ => return application_object(objects, req, reply),
            },
        };
        // Every core class (and every application class with a `class_revision`) serves the same
        // class instance (0): its revision, nothing else; the Acknowledge Handler also its max
        // instance (attribute 2).
        if req.instance == 0 {
            let max_instance = req.class == class::ACKNOWLEDGE_HANDLER;
            return match req.service {
                ServiceCode::GetAttributeSingle => class_revision(req.data, revision, max_instance, reply),
                _ => Err(ServiceError::SERVICE_NOT_SUPPORTED),
            };
        }
        match req.class {
            class::IDENTITY => self.identity_service(req, reply, now),
            class::DEVICENET => self.devicenet_service(req, reply, now),
            class::ASSEMBLY => self.assembly_service(req, reply),
            class::CONNECTION => self.connection_service(req, reply, now),
            class::ACKNOWLEDGE_HANDLER => self.ack_handler_service(req, reply),
            _ => router_service(req),
        }
    }
}

/// A class the core does not implement, served by the application's `objects`.
// Out of line: a large handler inlined here shares one frame with the core's classes, and the
// register shuffling between them costs some 55 bytes of the firmware's flash.
#[inline(never)]
fn application_object<H: ObjectHandler>(
    objects: &mut H,
    req: &Request<'_>,
    reply: &mut Reply<'_>,
) -> Result<(), ServiceError> {
    objects.handle(req, reply).unwrap_or(Err(ServiceError::OBJECT_DOES_NOT_EXIST))
}

/// Message Router instance services: no attribute is served.
fn router_service(req: &Request<'_>) -> Result<(), ServiceError> {
    match (req.instance, req.service) {
        (1, ServiceCode::GetAttributeSingle) => Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED),
        (1, _) => Err(ServiceError::SERVICE_NOT_SUPPORTED),
        _ => Err(ServiceError::OBJECT_DOES_NOT_EXIST),
    }
}
