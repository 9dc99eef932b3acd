//! The Assembly object (class 0x04): the poll connection's input (produced) and output
//! (consumed) images as two instances, whose numbers come from the configuration.

use crate::explicit::{Request, ServiceCode};
use crate::slave::{Event, Reply, ServiceError, SlaveNode};

impl SlaveNode {
    /// Assembly services: Get_Attribute_Single (data, size) and Set_Attribute_Single of the
    /// output data while the poll connection does not own it.
    pub(super) fn assembly_service(
        &mut self,
        req: &Request<'_>,
        reply: &mut Reply<'_>,
    ) -> Result<(), ServiceError> {
        let input = u16::from(self.config.input_assembly);
        let output = u16::from(self.config.output_assembly);
        if req.instance != input && req.instance != output {
            return Err(ServiceError::OBJECT_DOES_NOT_EXIST);
        }
        let is_input = req.instance == input;
        match req.service {
            ServiceCode::GetAttributeSingle => {
                let &[attr] = req.data else {
                    return Err(ServiceError::wrong_length(req.data, 1));
                };
                let data: &[u8] = if is_input { &self.input } else { &self.output };
                match attr {
                    3 => reply.bytes(data),
                    4 => {
                        let size =
                            if is_input { self.config.produced_size } else { self.config.consumed_size };
                        reply.u16(size)
                    }
                    _ => Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED),
                }
            }
            ServiceCode::SetAttributeSingle => {
                let (&attr, value) = req.data.split_first().ok_or(ServiceError::NOT_ENOUGH_DATA)?;
                match attr {
                    3 if is_input => Err(ServiceError::ATTRIBUTE_NOT_SETTABLE),
                    // The poll connection owns the outputs while it is established.
                    3 if self.poll.is_established() => Err(ServiceError::DEVICE_STATE_CONFLICT),
                    3 => {
                        // Checked in place: no helper's Result to carry (firmware size).
                        let consumed = usize::from(self.config.consumed_size);
                        if value.len() != consumed {
                            return Err(ServiceError::wrong_length(value, consumed));
                        }
                        self.output.clear();
                        let _ = self.output.extend_from_slice(value);
                        self.push_event(Event::OutputReceived);
                        Ok(())
                    }
                    4 => Err(ServiceError::ATTRIBUTE_NOT_SETTABLE),
                    _ => Err(ServiceError::ATTRIBUTE_NOT_SUPPORTED),
                }
            }
            _ => Err(ServiceError::SERVICE_NOT_SUPPORTED),
        }
    }
}
