//! The Sparkplug B payload (Eclipse Tahu `sparkplug_b.proto`, package
//! `org.eclipse.tahu.protobuf`), the part this edge node writes and reads, as `prost` messages.
//!
//! These are the declarations `prost-build` generates from the `.proto` file, committed so that a
//! build needs no `protoc`; field numbers and types are the `.proto`'s. Fields left out (data sets,
//! templates, metadata, extensions) are skipped by the decoder like any unknown field.

/// `Payload`: one Sparkplug message.
#[derive(Clone, PartialEq, prost::Message)]
pub struct Payload {
    /// Milliseconds since the Unix epoch, when the message was made.
    #[prost(uint64, optional, tag = "1")]
    pub timestamp: Option<u64>,
    /// The metrics.
    #[prost(message, repeated, tag = "2")]
    pub metrics: Vec<Metric>,
    /// The sequence number 0..=255 (absent in NDEATH).
    #[prost(uint64, optional, tag = "3")]
    pub seq: Option<u64>,
    /// Not used by this edge node.
    #[prost(string, optional, tag = "4")]
    pub uuid: Option<String>,
    /// Not used by this edge node.
    #[prost(bytes = "vec", optional, tag = "5")]
    pub body: Option<Vec<u8>>,
}

/// `Payload.Metric`.
#[derive(Clone, PartialEq, prost::Message)]
pub struct Metric {
    /// The metric's name (`Inputs/phase_a`).
    #[prost(string, optional, tag = "1")]
    pub name: Option<String>,
    /// An alias (not used: every metric is sent by name).
    #[prost(uint64, optional, tag = "2")]
    pub alias: Option<u64>,
    /// Milliseconds since the Unix epoch, when the value was taken.
    #[prost(uint64, optional, tag = "3")]
    pub timestamp: Option<u64>,
    /// A [`DataType`] code.
    #[prost(uint32, optional, tag = "4")]
    pub datatype: Option<u32>,
    /// Stored while the broker was away and sent later (store-and-forward).
    #[prost(bool, optional, tag = "5")]
    pub is_historical: Option<bool>,
    /// Not stored by the host.
    #[prost(bool, optional, tag = "6")]
    pub is_transient: Option<bool>,
    /// The value is null (not known yet).
    #[prost(bool, optional, tag = "7")]
    pub is_null: Option<bool>,
    /// Properties (`engUnit`, `readOnly`).
    #[prost(message, optional, tag = "9")]
    pub properties: Option<PropertySet>,
    /// The value.
    #[prost(oneof = "Value", tags = "10, 11, 12, 13, 14, 15, 16")]
    pub value: Option<Value>,
}

/// `Payload.Metric.value`.
#[derive(Clone, PartialEq, prost::Oneof)]
pub enum Value {
    /// Int8..Int32, UInt8..UInt32.
    #[prost(uint32, tag = "10")]
    IntValue(u32),
    /// Int64, UInt64, DateTime.
    #[prost(uint64, tag = "11")]
    LongValue(u64),
    /// Float.
    #[prost(float, tag = "12")]
    FloatValue(f32),
    /// Double.
    #[prost(double, tag = "13")]
    DoubleValue(f64),
    /// Boolean.
    #[prost(bool, tag = "14")]
    BooleanValue(bool),
    /// String, Text, UUID.
    #[prost(string, tag = "15")]
    StringValue(String),
    /// Bytes, File.
    #[prost(bytes, tag = "16")]
    BytesValue(Vec<u8>),
}

/// `Payload.PropertySet`: `keys[i]` names `values[i]`.
#[derive(Clone, PartialEq, prost::Message)]
pub struct PropertySet {
    /// The names.
    #[prost(string, repeated, tag = "1")]
    pub keys: Vec<String>,
    /// The values.
    #[prost(message, repeated, tag = "2")]
    pub values: Vec<PropertyValue>,
}

/// `Payload.PropertyValue` (the scalar kinds).
#[derive(Clone, PartialEq, prost::Message)]
pub struct PropertyValue {
    /// A [`DataType`] code.
    #[prost(uint32, optional, tag = "1")]
    pub r#type: Option<u32>,
    /// The value is null.
    #[prost(bool, optional, tag = "2")]
    pub is_null: Option<bool>,
    /// The value.
    #[prost(oneof = "PropertyValueKind", tags = "3, 4, 7, 8")]
    pub value: Option<PropertyValueKind>,
}

/// `Payload.PropertyValue.value` (the scalar kinds).
#[derive(Clone, PartialEq, prost::Oneof)]
pub enum PropertyValueKind {
    /// Int8..UInt32.
    #[prost(uint32, tag = "3")]
    IntValue(u32),
    /// Int64, UInt64.
    #[prost(uint64, tag = "4")]
    LongValue(u64),
    /// Boolean.
    #[prost(bool, tag = "7")]
    BooleanValue(bool),
    /// String.
    #[prost(string, tag = "8")]
    StringValue(String),
}

/// `DataType`: the Sparkplug B data type codes this edge node uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u32)]
pub enum DataType {
    /// 8-bit unsigned.
    UInt8 = 5,
    /// 16-bit unsigned.
    UInt16 = 6,
    /// 32-bit unsigned.
    UInt32 = 7,
    /// 64-bit unsigned.
    UInt64 = 8,
    /// 64-bit float.
    Double = 10,
    /// Boolean.
    Boolean = 11,
    /// UTF-8 string.
    String = 12,
    /// Bytes.
    Bytes = 17,
}
