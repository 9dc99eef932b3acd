//! The Message Router (class 0x02): hands each explicit request to the object class it names,
//! and serves its own class revision.

use super::class_revision;
use crate::explicit::{Request, ServiceCode};
use crate::objects::class;
use crate::slave::{ObjectHandler, Reply, ServiceError, SlaveNode};
use crate::time::Instant;

impl SlaveNode {
    /// Routes `req` to the class it names; classes the core does not implement go to `objects`.
    pub(in crate::slave) fn dispatch<H: ObjectHandler>(
        &mut self,
        req: &Request<'_>,
        reply: &mut Reply<'_>,
        now: Instant,
        objects: &mut H,
    ) -> Result<(), ServiceError> {
        match req.class {
            class::IDENTITY => self.identity_service(req, reply),
            class::MESSAGE_ROUTER => self.router_service(req, reply),
            class::DEVICENET => self.devicenet_service(req, reply, now),
            class::ASSEMBLY => self.assembly_service(req, reply),
            class::CONNECTION => self.connection_service(req, reply, now),
            _ => objects.handle(req, reply).unwrap_or(Err(ServiceError::OBJECT_DOES_NOT_EXIST)),
        }
    }

    /// Message Router services: the class revision only.
    fn router_service(&mut self, req: &Request<'_>, reply: &mut Reply<'_>) -> Result<(), ServiceError> {
        match (req.instance, req.service) {
            (0, ServiceCode::GetAttributeSingle) => class_revision(req.data, 1, reply),
            (1, ServiceCode::GetAttributeSingle) => Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED),
            (0 | 1, _) => Err(ServiceError::SERVICE_NOT_SUPPORTED),
            _ => Err(ServiceError::OBJECT_DOES_NOT_EXIST),
        }
    }
}
