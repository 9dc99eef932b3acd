//! The node manager of the namespace [`NAMESPACE`]: the `DeviceNet` folder, kept in step with the
//! scanner's state by [`sync`], and the methods on each node's object, carried out through the
//! console's command queue ([`Shared::commands`]) and recorded in its audit log.
//!
//! Node ids are strings in the namespace: `MAC05`, `MAC05/Identity/VendorId`, `MAC05/Open`,
//! `Scanner/Cycles`. Objects are added as the scan list becomes known (a network scan first,
//! then each node's identity); none is removed while the server runs.

use crate::auth::Accounts;
use crate::values::{self, Folder, Value};
use async_trait::async_trait;
use dnet_scanner::audit::{AuditEntry, Via};
use dnet_scanner::breaker::{breaker_output, BreakerCommand};
use dnet_scanner::model::{ConsoleCommand, Reply, Shared};
use opcua::server::address_space::{
    AccessLevel, AddressSpace, MethodBuilder, ObjectBuilder, VariableBuilder,
};
use opcua::server::diagnostics::NamespaceMetadata;
use opcua::server::node_manager::memory::{InMemoryNodeManager, InMemoryNodeManagerImpl};
use opcua::server::node_manager::{MethodCall, RequestContext, ServerContext};
use opcua::server::SubscriptionCache;
use opcua::sync::RwLock;
use opcua::types::{
    DataTypeId, DataValue, EUInformation, ExtensionObject, Identifier, LocalizedText, NodeId, ObjectId,
    ObjectTypeId, QualifiedName, StatusCode, VariableTypeId, Variant,
};
use std::collections::{HashMap, HashSet};
use std::sync::{mpsc, Arc};
use std::time::Duration;

/// The namespace URI of the scanner's nodes.
pub const NAMESPACE: &str = "urn:dnet-master:devicenet";

/// How long a method waits for the scanner's loop to carry out its command (the console's wait).
pub const COMMAND_TIMEOUT: Duration = dnet_scanner::ui::COMMAND_TIMEOUT;

/// The namespace of UN/CEFACT units in EUInformation (OPC 10000-8 v1.05 §5.6.3.3).
const UNECE_NAMESPACE: &str = "http://www.opcfoundation.org/UA/units/un/cefact";

/// The node manager serving [`NAMESPACE`].
pub type DnetNodeManager = InMemoryNodeManager<DnetNodes>;

/// The methods of a node's object.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Method {
    /// Breaker command 1.
    Open,
    /// Breaker command 2.
    Close,
    /// The whole output image, one ByteString argument.
    SetOutput,
}

impl Method {
    fn name(self) -> &'static str {
        match self {
            Method::Open => "Open",
            Method::Close => "Close",
            Method::SetOutput => "SetOutput",
        }
    }

    fn from_name(text: &str) -> Option<Method> {
        [Method::Open, Method::Close, Method::SetOutput].into_iter().find(|m| m.name() == text)
    }
}

/// The implementation behind [`DnetNodeManager`].
pub struct DnetNodes {
    namespace: u16,
    shared: Arc<Shared>,
    accounts: Arc<Accounts>,
}

impl DnetNodes {
    /// A node manager over `shared` whose methods are allowed by `accounts`; `namespace` is the
    /// index the server gave [`NAMESPACE`].
    #[must_use]
    pub fn new(namespace: u16, shared: Arc<Shared>, accounts: Arc<Accounts>) -> DnetNodes {
        DnetNodes { namespace, shared, accounts }
    }

    /// The id of `path` in the namespace.
    #[must_use]
    pub fn id(&self, path: &str) -> NodeId {
        NodeId::new(self.namespace, path)
    }

    /// `name` in the namespace, as a browse name.
    #[must_use]
    pub fn browse_name(&self, name: &str) -> QualifiedName {
        QualifiedName::new(self.namespace, name)
    }

    /// The MAC and method a method id names (`MAC05/Close`).
    fn method_of(&self, id: &NodeId) -> Option<(u8, Method)> {
        if id.namespace != self.namespace {
            return None;
        }
        let Identifier::String(s) = &id.identifier else { return None };
        let (node, method) = s.as_ref().split_once('/')?;
        Some((node.strip_prefix("MAC")?.parse().ok()?, Method::from_name(method)?))
    }

    /// Carries out one call for `user`; the status and what the audit log records.
    async fn execute(&self, mac: u8, method: Method, args: &[Variant]) -> (StatusCode, String) {
        let node = self.shared.state.lock().ok().and_then(|s| s.nodes.iter().find(|n| n.mac == mac).cloned());
        let Some(node) = node else {
            return (StatusCode::BadNodeIdUnknown, format!("failed: MAC {mac} is not in the scan list"));
        };
        let data = match method {
            Method::Open => breaker_output(BreakerCommand::Open, &node.output, node.output_size),
            Method::Close => breaker_output(BreakerCommand::Close, &node.output, node.output_size),
            Method::SetOutput => match args {
                [Variant::ByteString(b)] => b.value.clone().unwrap_or_default(),
                _ => {
                    return (StatusCode::BadInvalidArgument, "refused: SetOutput takes one ByteString".into())
                }
            },
        };
        if matches!(method, Method::Open | Method::Close) && !values::is_breaker(&node) {
            return (StatusCode::BadNotSupported, format!("refused: MAC {mac} is not a breaker"));
        }
        let shared = Arc::clone(&self.shared);
        let reply = tokio::task::spawn_blocking(move || send(&shared, mac, data)).await;
        match reply {
            Ok(Ok(_)) => (StatusCode::Good, "ok".into()),
            Ok(Err(e)) => (StatusCode::BadInvalidState, format!("failed: {e}")),
            Err(_) => (StatusCode::BadInternalError, "failed: the command's thread stopped".into()),
        }
    }
}

/// Puts `data` in the node's output image through the scanner's loop and waits for its answer.
fn send(shared: &Shared, mac: u8, data: Vec<u8>) -> Reply {
    let (reply, answer) = mpsc::channel();
    shared
        .commands
        .lock()
        .map_err(|_| "the scanner is not taking commands".to_string())?
        .send(ConsoleCommand::SetOutput { mac, data, reply })
        .map_err(|_| "the scanner is not running".to_string())?;
    match answer.recv_timeout(COMMAND_TIMEOUT) {
        Ok(r) => r,
        Err(mpsc::RecvTimeoutError::Timeout) => {
            Err(format!("no answer from the scanner within {} s", COMMAND_TIMEOUT.as_secs()))
        }
        Err(mpsc::RecvTimeoutError::Disconnected) => Err("the scanner stopped before answering".into()),
    }
}

/// The text of a call for the audit log: `close`, `output 01 02`.
fn what(method: Method, args: &[Variant]) -> String {
    match (method, args) {
        (Method::SetOutput, [Variant::ByteString(b)]) => {
            let bytes: Vec<String> = b.value.iter().flatten().map(|x| format!("{x:02X}")).collect();
            format!("output {}", bytes.join(" "))
        }
        _ => method.name().to_ascii_lowercase(),
    }
}

#[async_trait]
impl InMemoryNodeManagerImpl for DnetNodes {
    async fn init(&self, address_space: &mut AddressSpace, _context: ServerContext) {
        ObjectBuilder::new(&self.id("DeviceNet"), self.browse_name("DeviceNet"), "DeviceNet")
            .description("The DeviceNet scanner and every node of its scan list")
            .has_type_definition(ObjectTypeId::FolderType)
            .organized_by(ObjectId::ObjectsFolder)
            .insert(address_space);
        ObjectBuilder::new(&self.id("Scanner"), self.browse_name("Scanner"), "Scanner")
            .has_type_definition(ObjectTypeId::BaseObjectType)
            .organized_by(self.id("DeviceNet"))
            .insert(address_space);
    }

    fn name(&self) -> &str {
        "dnet-master"
    }

    fn namespaces(&self) -> Vec<NamespaceMetadata> {
        vec![NamespaceMetadata {
            is_namespace_subset: Some(false),
            namespace_uri: NAMESPACE.to_string(),
            namespace_index: self.namespace,
            ..Default::default()
        }]
    }

    async fn call(
        &self,
        context: &RequestContext,
        _address_space: &RwLock<AddressSpace>,
        methods_to_call: &mut [&mut &mut MethodCall],
    ) -> Result<(), StatusCode> {
        let token = context.user_token().clone();
        let user = if token.is_anonymous() { "anonymous".to_string() } else { token.0.clone() };
        for call in methods_to_call.iter_mut() {
            let Some((mac, method)) = self.method_of(call.method_id()) else {
                call.set_status(StatusCode::BadMethodInvalid);
                continue;
            };
            let what = what(method, call.arguments());
            let (status, result) = match self.accounts.may_operate(&token) {
                Ok(()) => self.execute(mac, method, call.arguments()).await,
                Err(why) => (StatusCode::BadUserAccessDenied, format!("refused: {why}")),
            };
            // A log that cannot be written must not hide the command's result from the caller.
            let _ = self.shared.audit.record(&AuditEntry::now(&user, Via::OpcUa, Some(mac), &what, &result));
            call.set_status(status);
            if status.is_good() {
                call.set_outputs(Vec::new());
            }
        }
        Ok(())
    }
}

/// What [`sync`] has put in the address space, and the values last written.
#[derive(Default)]
pub struct Synced {
    objects: HashSet<u8>,
    methods: HashSet<(u8, &'static str)>,
    values: HashMap<NodeId, Variant>,
}

/// Brings the address space in step with the scanner's state: adds the objects and variables
/// that are new, and writes the values that changed (notifying subscriptions). Returns how many
/// values changed.
pub fn sync(manager: &DnetNodeManager, subscriptions: &SubscriptionCache, synced: &mut Synced) -> usize {
    let nodes = manager.inner();
    let Some(state) = nodes.shared.state.lock().ok().map(|s| s.clone()) else {
        return 0;
    };
    let mut changes: Vec<(NodeId, Variant)> = Vec::new();
    {
        let mut space = manager.address_space().write();
        let scanner = nodes.id("Scanner");
        for v in values::scanner_values(&state) {
            let id = nodes.id(&format!("Scanner/{}", v.name));
            track(&mut space, synced, &mut changes, &scanner, id, &v);
        }
        for node in &state.nodes {
            let object = add_object(nodes, &mut space, synced, node.mac);
            let breaker = values::is_breaker(node);
            for method in [Method::Open, Method::Close, Method::SetOutput] {
                if method != Method::SetOutput && !breaker {
                    continue;
                }
                if synced.methods.insert((node.mac, method.name())) {
                    add_method(nodes, &mut space, &object, node.mac, method);
                }
            }
            for v in values::node_values(node) {
                let name = values::node_name(node.mac);
                let parent = match v.folder.name() {
                    Some(f) => nodes.id(&format!("{name}/{f}")),
                    None => object.clone(),
                };
                let id = nodes.id(&format!("{name}/{}", v.path()));
                track(&mut space, synced, &mut changes, &parent, id, &v);
            }
        }
    }
    let count = changes.len();
    if count > 0 {
        let now = DataValue::new_now(Variant::Empty).source_timestamp;
        let values = changes.into_iter().map(|(id, value)| {
            let mut dv = DataValue::new_now(value);
            dv.source_timestamp = now;
            (id, dv)
        });
        let values: Vec<(NodeId, DataValue)> = values.collect();
        // Every id was inserted above: an error would be a node deleted under us; nothing to do.
        let _ = manager.set_values(subscriptions, values.iter().map(|(id, dv)| (id, None, dv.clone())));
    }
    count
}

/// Adds the variable of `v` under `parent` when it is new; notes its value when it changed.
fn track(
    space: &mut AddressSpace,
    synced: &mut Synced,
    changes: &mut Vec<(NodeId, Variant)>,
    parent: &NodeId,
    id: NodeId,
    v: &Value,
) {
    match synced.values.get(&id) {
        Some(old) if *old == v.value => return,
        Some(_) => {}
        None => add_variable(space, parent, &id, v),
    }
    synced.values.insert(id.clone(), v.value.clone());
    changes.push((id, v.value.clone()));
}

/// The node's object and its folders, added the first time the MAC is seen; its id.
fn add_object(nodes: &DnetNodes, space: &mut AddressSpace, synced: &mut Synced, mac: u8) -> NodeId {
    let name = values::node_name(mac);
    let object = nodes.id(&name);
    if synced.objects.insert(mac) {
        ObjectBuilder::new(&object, nodes.browse_name(&name), name.as_str())
            .description(format!("The node at MAC ID {mac}"))
            .has_type_definition(ObjectTypeId::BaseObjectType)
            .organized_by(nodes.id("DeviceNet"))
            .insert(space);
        for folder in Folder::SUBFOLDERS {
            let Some(f) = folder.name() else { continue };
            ObjectBuilder::new(&nodes.id(&format!("{name}/{f}")), nodes.browse_name(f), f)
                .has_type_definition(ObjectTypeId::FolderType)
                .component_of(object.clone())
                .insert(space);
        }
    }
    object
}

fn add_variable(space: &mut AddressSpace, parent: &NodeId, id: &NodeId, v: &Value) {
    let Identifier::String(path) = &id.identifier else { return };
    let builder =
        VariableBuilder::new(id, QualifiedName::new(id.namespace, v.name.as_str()), v.name.as_str())
            .data_type(v.data_type)
            .value(v.value.clone())
            .access_level(AccessLevel::CURRENT_READ)
            .user_access_level(AccessLevel::CURRENT_READ)
            .component_of(parent.clone());
    let builder = match v.unit {
        Some(_) => builder.has_type_definition(VariableTypeId::AnalogItemType),
        None => builder.has_type_definition(VariableTypeId::BaseDataVariableType),
    };
    builder.insert(space);
    if let Some(unit) = v.unit {
        let eu = EUInformation {
            namespace_uri: UNECE_NAMESPACE.into(),
            unit_id: unit.unit_id(),
            display_name: LocalizedText::new("", unit.symbol()),
            description: LocalizedText::new("", unit.description()),
        };
        let eu_id = NodeId::new(id.namespace, format!("{}/EngineeringUnits", path.as_ref()));
        VariableBuilder::new(&eu_id, "EngineeringUnits", "EngineeringUnits")
            .data_type(DataTypeId::EUInformation)
            .value(Variant::from(ExtensionObject::from_message(eu)))
            .access_level(AccessLevel::CURRENT_READ)
            .user_access_level(AccessLevel::CURRENT_READ)
            .has_type_definition(VariableTypeId::PropertyType)
            .property_of(id.clone())
            .insert(space);
    }
}

fn add_method(nodes: &DnetNodes, space: &mut AddressSpace, object: &NodeId, mac: u8, method: Method) {
    let name = values::node_name(mac);
    let id = nodes.id(&format!("{name}/{}", method.name()));
    let description = match method {
        Method::Open => "Open the breaker (operator or engineer account)",
        Method::Close => "Close the breaker (operator or engineer account)",
        Method::SetOutput => "Write the whole output image (operator or engineer account)",
    };
    let builder = MethodBuilder::new(&id, nodes.browse_name(method.name()), method.name())
        .description(description)
        .executable(true)
        .user_executable(true)
        .component_of(object.clone());
    let builder = match method {
        Method::SetOutput => builder.input_args(
            space,
            &nodes.id(&format!("{name}/{}/InputArguments", method.name())),
            &[("Data", DataTypeId::ByteString).into()],
        ),
        _ => builder,
    };
    builder.insert(space);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_audit_text_names_the_bytes_written() {
        let args = [Variant::from(opcua::types::ByteString::from(vec![1u8, 0xAB]))];
        assert_eq!(what(Method::SetOutput, &args), "output 01 AB");
        assert_eq!(what(Method::Close, &[]), "close");
    }
}
