-- devicenet.lua: a Wireshark dissector for DeviceNet on CAN (protocol "dnetx").
--
-- Decodes what Wireshark's built-in DeviceNet dissector leaves raw: Group 2 explicit messages
-- (services, class/instance/attribute, values, Allocate/Release, error responses by name), explicit
-- and I/O fragment reassembly, the duplicate MAC ID check, UCMM open/close, device heartbeat and
-- shutdown, and the Offline Connection Set (Group 4). The names and texts follow the project's Rust
-- decoder (master-core/src/decode.rs), so the Info column reads like `dnet-master decode`.
--
-- Install: copy this file to ~/.local/lib/wireshark/plugins/ (or run
-- `tshark -X lua_script:devicenet.lua -r FILE`). It registers itself for every 11-bit CAN
-- identifier 0x000-0x7EF in the "can.id" table, so SocketCAN captures (link type 227) decode with
-- no further option; it is also offered under Decode As... (CAN next level dissector).
--
-- Protocol facts: the guide's protocol reference, docs/src/protocol/ (sections cited as "protocol §n").
-- Reassembly is done in Lua tables keyed by device MAC and direction on the first pass
-- (pinfo.visited false); what each frame needs later (the reassembled bytes, the request a
-- response answers, the body format) is stored per frame number, so a frame dissected again in
-- the GUI shows the same tree.

local dnetx = Proto("dnetx", "DeviceNet (explicit messaging, fragmentation, connection set)")

---------------------------------------------------------------------------------------------
-- Names (devicenet/src/objects.rs, devicenet/src/explicit.rs; protocol §1-§3, §5, §6)

local group_names = { [1] = "Group 1", [2] = "Group 2", [3] = "Group 3", [4] = "Group 4" }

-- protocol §1.3
local g1_names = {
    [12] = "Slave's multicast poll response",
    [13] = "Slave's I/O change-of-state/cyclic message",
    [14] = "Slave's I/O bit-strobe response",
    [15] = "Slave's I/O poll response or change-of-state/cyclic acknowledge",
}
-- protocol §1.2
local g2_names = {
    [0] = "Master's I/O bit-strobe command",
    [1] = "Master's I/O multicast poll command",
    [2] = "Master's change-of-state/cyclic acknowledge",
    [3] = "Slave's explicit/unconnected response",
    [4] = "Master's explicit request",
    [5] = "Master's I/O poll command/change-of-state/cyclic message",
    [6] = "Group 2 Only unconnected explicit request",
    [7] = "Duplicate MAC ID check message",
}
-- protocol §1.4
local g3_names = {
    [5] = "Unconnected (UCMM) explicit response",
    [6] = "Unconnected (UCMM) explicit request",
    [7] = "invalid",
}
local g4_names = {
    [0x2C] = "Communication Faulted response",
    [0x2D] = "Communication Faulted request",
    [0x2E] = "Offline Ownership response",
    [0x2F] = "Offline Ownership request",
}

local service_names = {
    [0x01] = "Get_Attributes_All", [0x02] = "Set_Attributes_All", [0x03] = "Get_Attribute_List",
    [0x04] = "Set_Attribute_List", [0x05] = "Reset", [0x06] = "Start", [0x07] = "Stop",
    [0x08] = "Create", [0x09] = "Delete", [0x0A] = "Multiple_Service_Packet",
    [0x0D] = "Apply_Attributes", [0x0E] = "Get_Attribute_Single", [0x10] = "Set_Attribute_Single",
    [0x11] = "Find_Next_Object_Instance", [0x14] = "Error_Response", [0x15] = "Restore",
    [0x16] = "Save", [0x17] = "NOP", [0x18] = "Get_Member", [0x19] = "Set_Member",
    [0x1A] = "Insert_Member", [0x1B] = "Remove_Member", [0x1C] = "Group_Sync",
    [0x4B] = "Allocate_Master/Slave_Connection_Set", [0x4C] = "Release_Master/Slave_Connection_Set",
    [0x4D] = "Device_Heartbeat", [0x4E] = "Device_Shutdown",
}

local class_names = {
    [0x01] = "Identity", [0x02] = "Message Router", [0x03] = "DeviceNet", [0x04] = "Assembly",
    [0x05] = "Connection", [0x0F] = "Parameter", [0x2B] = "Acknowledge Handler",
}

local attribute_names = {
    [0x01] = {
        [1] = "vendor ID", [2] = "device type", [3] = "product code", [4] = "revision",
        [5] = "status", [6] = "serial number", [7] = "product name", [8] = "state",
        [9] = "configuration consistency value", [10] = "heartbeat interval",
    },
    [0x03] = {
        [1] = "MAC ID", [2] = "baud rate", [3] = "bus-off interrupt", [4] = "bus-off counter",
        [5] = "allocation information", [6] = "MAC ID switch changed",
        [7] = "baud rate switch changed", [8] = "MAC ID switch value", [9] = "baud rate switch value",
    },
    [0x04] = { [3] = "data", [4] = "size" },
    [0x05] = {
        [1] = "state", [2] = "instance type", [3] = "transport class trigger",
        [4] = "produced connection ID", [5] = "consumed connection ID",
        [6] = "initial comm characteristics", [7] = "produced connection size",
        [8] = "consumed connection size", [9] = "expected packet rate",
        [12] = "watchdog timeout action", [13] = "produced connection path length",
        [14] = "produced connection path", [15] = "consumed connection path length",
        [16] = "consumed connection path", [17] = "production inhibit time",
    },
}

local general_status_names = {
    [0x00] = "success", [0x01] = "connection failure", [0x02] = "resource unavailable",
    [0x03] = "invalid parameter value", [0x04] = "path segment error",
    [0x05] = "path destination unknown", [0x06] = "partial transfer", [0x07] = "connection lost",
    [0x08] = "service not supported", [0x09] = "invalid attribute value",
    [0x0A] = "attribute list error", [0x0B] = "already in requested mode/state",
    [0x0C] = "object state conflict", [0x0D] = "object already exists",
    [0x0E] = "attribute not settable", [0x0F] = "privilege violation",
    [0x10] = "device state conflict", [0x11] = "reply data too large",
    [0x12] = "fragmentation of a primitive value", [0x13] = "not enough data",
    [0x14] = "attribute not supported", [0x15] = "too much data", [0x16] = "object does not exist",
    [0x17] = "service fragmentation sequence not in progress", [0x18] = "no stored attribute data",
    [0x19] = "store operation failure", [0x1A] = "routing failure, request packet too large",
    [0x1B] = "routing failure, response packet too large",
    [0x1C] = "missing attribute list entry data", [0x1D] = "invalid attribute value list",
    [0x1E] = "embedded service error", [0x1F] = "vendor specific error",
    [0x20] = "invalid parameter", [0x21] = "write-once value or medium already written",
    [0x22] = "invalid reply received", [0x25] = "key failure in path",
    [0x26] = "path size invalid", [0x27] = "unexpected attribute in list",
    [0x28] = "invalid member ID", [0x29] = "member not settable",
    [0x2A] = "Group 2 only server general failure",
}

-- protocol §3.4 (GC/AN additional codes of the connection set)
local additional_names = {
    [0xFF] = "no additional code", [0x01] = "allocation conflict",
    [0x02] = "invalid allocation/release choice",
    [0x03] = "invalid request on the Group 2 Only port",
    [0x04] = "resource unavailable for the requested connections",
}

local body_format_names = { [0] = "8/8", [1] = "8/16", [2] = "16/16", [3] = "16/8", [4] = "CIP path" }
local frag_type_names = { [0] = "first", [1] = "middle", [2] = "last", [3] = "ack" }
local ack_status_names = { [0] = "success", [1] = "too much data" }
local group_select_names = { [0] = "group 1", [1] = "group 2", [3] = "group 3", [15] = "node ping" }
local connection_state_names = {
    [0] = "non-existent", [1] = "configuring", [2] = "waiting for connection ID",
    [3] = "established", [4] = "timed out", [5] = "deferred delete",
}
local watchdog_action_names = {
    [0] = "transition to timed out", [1] = "auto delete", [2] = "auto reset", [3] = "deferred delete",
}
local identity_state_names = {
    [0] = "non-existent", [1] = "self testing", [2] = "standby", [3] = "operational",
    [4] = "major recoverable fault", [5] = "major unrecoverable fault",
}
-- protocol §3.4, bit 0 first
local choice_bits = {
    { 0x01, "explicit" }, { 0x02, "poll" }, { 0x04, "bit_strobe" }, { 0x08, "multicast_poll" },
    { 0x10, "change_of_state" }, { 0x20, "cyclic" }, { 0x40, "ack_suppression" }, { 0x80, "reserved" },
}

---------------------------------------------------------------------------------------------
-- Fields

local F = dnetx.fields
local function add_field(key, f) F[key] = f end

add_field("group", ProtoField.uint8("dnetx.group", "Message group", base.DEC, group_names))
add_field("msgid", ProtoField.uint8("dnetx.msgid", "Message ID", base.HEX))
add_field("message", ProtoField.string("dnetx.message", "Message"))
add_field("mac", ProtoField.uint8("dnetx.mac", "MAC ID (identifier)", base.DEC))
add_field("src", ProtoField.uint8("dnetx.src", "Source MAC ID", base.DEC))
add_field("dst", ProtoField.uint8("dnetx.dst", "Destination MAC ID", base.DEC))
add_field("summary", ProtoField.string("dnetx.summary", "Summary"))

add_field("hdr", ProtoField.uint8("dnetx.header", "Explicit header", base.HEX))
add_field("hdr_frag", ProtoField.bool("dnetx.header.frag", "Fragmented", 8, nil, 0x80))
add_field("hdr_xid", ProtoField.uint8("dnetx.header.xid", "XID", base.DEC, nil, 0x40))
add_field("hdr_mac", ProtoField.uint8("dnetx.header.mac", "MAC ID (header)", base.DEC, nil, 0x3F))

add_field("rr", ProtoField.bool("dnetx.response", "Response (R/R)", 8, nil, 0x80))
add_field("service", ProtoField.uint8("dnetx.service", "Service", base.HEX, service_names, 0x7F))
add_field("service_name", ProtoField.string("dnetx.service.name", "Service name"))
add_field("class", ProtoField.uint16("dnetx.class", "Class", base.HEX, class_names))
add_field("instance", ProtoField.uint16("dnetx.instance", "Instance", base.DEC))
add_field("attribute", ProtoField.uint8("dnetx.attribute", "Attribute", base.DEC))
add_field("attribute_name", ProtoField.string("dnetx.attribute.name", "Attribute name"))
add_field("path_size", ProtoField.uint8("dnetx.path_size", "Path size (words)", base.DEC))
add_field("path", ProtoField.bytes("dnetx.path", "CIP path", base.SPACE))
add_field("data", ProtoField.bytes("dnetx.data", "Service data", base.SPACE))
add_field("value", ProtoField.string("dnetx.value", "Value"))
add_field("body_format", ProtoField.uint8("dnetx.body_format", "Message body format", base.DEC, body_format_names, 0x0F))
add_field("body_format_assumed", ProtoField.bool("dnetx.body_format.assumed", "Body format 8/8 assumed (no Allocate response seen)"))

add_field("alloc_choice", ProtoField.uint8("dnetx.alloc.choice", "Allocation choice", base.HEX))
add_field("release_choice", ProtoField.uint8("dnetx.release.choice", "Release choice", base.HEX))
local choice_fields = {}
for i, b in ipairs(choice_bits) do
    local f = ProtoField.bool("dnetx.choice." .. b[2], b[2], 8, nil, b[1])
    choice_fields[i] = f
    add_field("choice_" .. b[2], f)
end
add_field("allocator", ProtoField.uint8("dnetx.alloc.allocator", "Allocator MAC ID", base.DEC, nil, 0x3F))

add_field("err_general", ProtoField.uint8("dnetx.error.general", "General status", base.HEX, general_status_names))
add_field("err_additional", ProtoField.uint8("dnetx.error.additional", "Additional code", base.HEX, additional_names))

add_field("frag_type", ProtoField.uint8("dnetx.frag.type", "Fragment type", base.DEC, frag_type_names, 0xC0))
add_field("frag_count", ProtoField.uint8("dnetx.frag.count", "Fragment count", base.DEC, nil, 0x3F))
add_field("frag_ack_status", ProtoField.uint8("dnetx.frag.ack_status", "Acknowledge status", base.HEX, ack_status_names))
add_field("frag_data", ProtoField.bytes("dnetx.frag.data", "Fragment data", base.SPACE))
add_field("frag_note", ProtoField.string("dnetx.frag.note", "Reassembly"))
add_field("fragment", ProtoField.framenum("dnetx.fragment", "Fragment in frame"))
add_field("reassembled_in", ProtoField.framenum("dnetx.reassembled_in", "Reassembled in frame"))
add_field("reassembled", ProtoField.bytes("dnetx.reassembled", "Reassembled message", base.SPACE))
add_field("reassembled_len", ProtoField.uint16("dnetx.reassembled.length", "Reassembled length", base.DEC))

add_field("io_data", ProtoField.bytes("dnetx.io.data", "I/O data", base.SPACE))
add_field("io_len", ProtoField.uint16("dnetx.io.length", "I/O data length", base.DEC))
add_field("io_inferred", ProtoField.bool("dnetx.io.size_inferred", "Size inferred from fragment bytes"))

add_field("dup_rr", ProtoField.bool("dnetx.dupmac.response", "Response", 8, nil, 0x80))
add_field("dup_port", ProtoField.uint8("dnetx.dupmac.port", "Physical port", base.DEC, nil, 0x7F))
add_field("vendor", ProtoField.uint16("dnetx.vendor", "Vendor ID", base.HEX))
add_field("serial", ProtoField.uint32("dnetx.serial", "Serial number", base.HEX))

add_field("ucmm_group", ProtoField.uint8("dnetx.ucmm.group_select", "Group select", base.DEC, group_select_names, 0xF0))
add_field("ucmm_src_msgid", ProtoField.uint8("dnetx.ucmm.source_msgid", "Source message ID", base.DEC, nil, 0x0F))
add_field("ucmm_dst_msgid", ProtoField.uint8("dnetx.ucmm.dest_msgid", "Destination message ID", base.DEC, nil, 0xF0))
add_field("conn_instance", ProtoField.uint16("dnetx.connection_instance", "Connection instance", base.DEC))

add_field("hb_instance", ProtoField.uint16("dnetx.heartbeat.instance", "Identity instance", base.DEC))
add_field("hb_state", ProtoField.uint8("dnetx.heartbeat.state", "Identity state", base.DEC, identity_state_names))
add_field("hb_flags", ProtoField.uint8("dnetx.heartbeat.flags", "Fault flags", base.HEX))
add_field("hb_df", ProtoField.bool("dnetx.heartbeat.flags.df", "DF device fault", 8, nil, 0x01))
add_field("hb_uf", ProtoField.bool("dnetx.heartbeat.flags.uf", "UF user fault", 8, nil, 0x02))
add_field("hb_sf", ProtoField.bool("dnetx.heartbeat.flags.sf", "SF system fault", 8, nil, 0x04))
add_field("hb_ev", ProtoField.bool("dnetx.heartbeat.flags.ev", "EV event", 8, nil, 0x08))
add_field("hb_ccv", ProtoField.uint16("dnetx.heartbeat.ccv", "Configuration consistency value", base.HEX))
add_field("sd_class", ProtoField.uint16("dnetx.shutdown.class", "Class", base.HEX))
add_field("sd_instance", ProtoField.uint16("dnetx.shutdown.instance", "Instance", base.DEC))
add_field("sd_code", ProtoField.uint16("dnetx.shutdown.code", "Shutdown code", base.HEX))

add_field("off_match", ProtoField.bool("dnetx.offline.match", "Match (1 exact MAC ID, 0 mask)", 8, nil, 0x40))
add_field("off_value", ProtoField.uint8("dnetx.offline.value", "MAC ID value", base.DEC, nil, 0x3F))
add_field("off_delay", ProtoField.uint8("dnetx.offline.delay_offset", "Time-delay byte offset", base.DEC))
add_field("off_new_mac", ProtoField.uint8("dnetx.offline.new_mac", "New MAC ID", base.DEC))
add_field("off_client", ProtoField.uint8("dnetx.offline.client_mac", "Tool (client) MAC ID", base.DEC))
add_field("off_port", ProtoField.uint8("dnetx.offline.port", "Physical port", base.DEC))

local ef_malformed = ProtoExpert.new("dnetx.malformed", "Malformed DeviceNet message", expert.group.MALFORMED, expert.severity.WARN)
local ef_dropped = ProtoExpert.new("dnetx.frag.dropped", "Fragment dropped from reassembly", expert.group.SEQUENCE, expert.severity.NOTE)
local ef_protocol = ProtoExpert.new("dnetx.frag.protocol_error", "Fragmentation protocol error", expert.group.SEQUENCE, expert.severity.WARN)
local ef_error = ProtoExpert.new("dnetx.error", "Error response", expert.group.RESPONSE_CODE, expert.severity.NOTE)
dnetx.experts = { ef_malformed, ef_dropped, ef_protocol, ef_error }

local f_can_id = Field.new("can.id")

---------------------------------------------------------------------------------------------
-- Text helpers (the texts of master-core/src/decode.rs)

local function hex(s, i, j)
    i = i or 1
    j = j or #s
    local t = {}
    for k = i, j do t[#t + 1] = string.format("%02X", s:byte(k)) end
    return table.concat(t, " ")
end

local function le16(s, i) return s:byte(i) + 256 * s:byte(i + 1) end
local function le32(s, i) return le16(s, i) + 65536 * le16(s, i + 2) end

local function service_text(code)
    local n = service_names[code]
    if n then return n end
    return string.format("service 0x%02X", code)
end

local function class_text(class)
    local n = class_names[class]
    if n then return string.format("%s(%d)", n, class) end
    return string.format("class 0x%02X", class)
end

local function attribute_name(class, instance, attribute)
    if instance == 0 then
        if attribute == 1 then return "revision" end
        if attribute == 2 then return "max instance" end
        return nil
    end
    local t = attribute_names[class]
    return t and t[attribute]
end

local function attribute_text(class, instance, attribute)
    local n = attribute_name(class, instance, attribute)
    if n then return string.format("attr %d (%s)", attribute, n) end
    return string.format("attr %d", attribute)
end

local function general_text(g)
    return string.format("%s (0x%02X)", general_status_names[g] or "unknown", g)
end

local function error_text(g, a)
    local add = additional_names[a]
    local at = add and string.format("0x%02X (%s)", a, add) or string.format("0x%02X", a)
    return string.format("%s, additional code %s", general_text(g), at)
end

local function body_format_text(code)
    return body_format_names[code] or string.format("reserved (%d)", code)
end

local function choice_text(c)
    if c == 0 then return "none" end
    local t = {}
    for _, b in ipairs(choice_bits) do
        if bit.band(c, b[1]) ~= 0 then t[#t + 1] = b[2] end
    end
    return table.concat(t, "|")
end

local function short_string(s)
    if #s >= 1 and s:byte(1) == #s - 1 then return s:sub(2) end
    return nil
end

-- An attribute value typed by class and attribute (decode.rs value_text).
local function value_text(class, instance, attribute, data)
    local n = #data
    local typed
    local u16 = n == 2 and le16(data, 1) or nil
    local u8 = n == 1 and data:byte(1) or nil
    if instance == 0 then
        if attribute == 1 and u16 then typed = tostring(u16) end
    elseif class == 0x01 then
        if attribute >= 1 and attribute <= 3 and u16 then typed = string.format("0x%04X (%d)", u16, u16)
        elseif attribute == 4 and n == 2 then typed = string.format("%d.%d", data:byte(1), data:byte(2))
        elseif attribute == 5 and u16 then typed = string.format("0x%04X", u16)
        elseif attribute == 6 and n == 4 then typed = string.format("0x%08X", le32(data, 1))
        elseif attribute == 7 then
            local s = short_string(data)
            if s then typed = '"' .. s .. '"' end
        elseif attribute == 8 and u8 then typed = string.format("%d (%s)", u8, identity_state_names[u8] or "unknown")
        end
    elseif class == 0x03 then
        if attribute == 5 and n == 2 then
            local choice, master = data:byte(1), data:byte(2)
            if master <= 63 then
                typed = string.format("allocated %s by master MAC %d", choice_text(choice), master)
            else
                typed = string.format("%s (not allocated)", choice_text(choice))
            end
        elseif attribute >= 1 and attribute <= 9 and attribute ~= 5 and u8 then typed = tostring(u8)
        end
    elseif class == 0x04 then
        if attribute == 4 and u16 then typed = string.format("%d bytes", u16) end
    elseif class == 0x05 then
        if attribute == 1 and u8 then typed = string.format("%d (%s)", u8, connection_state_names[u8] or "unknown")
        elseif attribute == 12 and u8 then typed = string.format("%d (%s)", u8, watchdog_action_names[u8] or "unknown")
        elseif attribute == 2 and u8 then
            typed = (u8 == 0 and "0 (explicit)") or (u8 == 1 and "1 (I/O)") or tostring(u8)
        elseif (attribute == 3 or attribute == 6) and u8 then typed = string.format("0x%02X", u8)
        elseif (attribute == 4 or attribute == 5) and u16 then typed = string.format("0x%03X", u16)
        elseif (attribute == 7 or attribute == 8) and u16 then typed = string.format("%d bytes", u16)
        elseif (attribute == 9 or attribute == 17) and u16 then typed = string.format("%d ms", u16)
        elseif (attribute == 13 or attribute == 15) and u16 then typed = tostring(u16)
        end
    end
    if typed then return typed end
    if n == 0 then return "(no data)" end
    return hex(data)
end

local function data_text(data)
    if #data == 0 then return "no data" end
    return string.format("%d bytes %s", #data, hex(data))
end

---------------------------------------------------------------------------------------------
-- Explicit message bodies: parse into a plain table (no tree), then text and tree from it.

-- Widths of class and instance per body format (protocol §3.1).
local format_widths = { [0] = { 1, 1 }, [1] = { 1, 2 }, [2] = { 2, 2 }, [3] = { 2, 1 } }

local function read_le(s, i, w)
    if w == 1 then return s:byte(i) end
    return le16(s, i)
end

-- A request body (service byte onward) in body format `fmt`. Returns a table
-- { service, class, instance, attribute, data_off, cls_off/w, inst_off/w, path } or nil, why.
-- Offsets are 1-based into `body`.
local function parse_request(body, fmt)
    if #body < 1 then return nil, "message truncated: needs 1 bytes, has 0" end
    local service = body:byte(1)
    if bit.band(service, 0x80) ~= 0 then return nil, "expected a request, found a response" end
    local r = { service = service }
    local w = format_widths[fmt]
    if w then
        local need = 1 + w[1] + w[2]
        if #body < need then
            return nil, string.format("message truncated: needs %d bytes, has %d", need, #body)
        end
        r.class, r.cls_off, r.cls_w = read_le(body, 2, w[1]), 2, w[1]
        r.instance, r.inst_off, r.inst_w = read_le(body, 2 + w[1], w[2]), 2 + w[1], w[2]
        r.data_off = need + 1
    elseif fmt == 4 then
        -- <path size in words> <EPATH>: 8-bit 20/24/30 xx, 16-bit 21/25/31 00 lo hi (decode.rs)
        if #body < 2 then return nil, "truncated: no path size" end
        local words = body:byte(2)
        local len = words * 2
        if #body - 2 < len then
            return nil, string.format("path of %d words, only %d bytes follow", words, #body - 2)
        end
        r.path_off, r.path_len = 3, len
        local i, stop = 3, 2 + len
        local ids, offs, widths = {}, {}, {}
        while i <= stop do
            local seg = body:byte(i)
            local slot, w16
            if seg == 0x20 or seg == 0x24 or seg == 0x30 then w16 = false
            elseif seg == 0x21 or seg == 0x25 or seg == 0x31 then w16 = true
            else return nil, string.format("unsupported path segment 0x%02X in %s", seg, hex(body, 3, stop)) end
            slot = (seg <= 0x21 and 1) or (seg <= 0x25 and 2) or 3
            local v, off, w
            if w16 then
                if i + 3 > stop then return nil, string.format("unsupported path segment 0x%02X in %s", seg, hex(body, 3, stop)) end
                v, off, w = le16(body, i + 2), i + 2, 2
                i = i + 4
            else
                if i + 1 > stop then return nil, string.format("unsupported path segment 0x%02X in %s", seg, hex(body, 3, stop)) end
                v, off, w = body:byte(i + 1), i + 1, 1
                i = i + 2
            end
            for k = 1, slot - 1 do
                if ids[k] == nil then return nil, "path segments out of order (class, instance, attribute): " .. hex(body, 3, stop) end
            end
            if ids[slot] ~= nil then return nil, "path segments out of order (class, instance, attribute): " .. hex(body, 3, stop) end
            ids[slot], offs[slot], widths[slot] = v, off, w
        end
        if ids[1] == nil or ids[2] == nil then return nil, "path without class and instance: " .. hex(body, 3, stop) end
        r.class, r.cls_off, r.cls_w = ids[1], offs[1], widths[1]
        r.instance, r.inst_off, r.inst_w = ids[2], offs[2], widths[2]
        if ids[3] then r.path_attribute, r.pattr_off, r.pattr_w = ids[3], offs[3], widths[3] end
        r.data_off = stop + 1
        r.cip_path = true
    else
        return nil, string.format("reserved message body format %d", fmt)
    end
    r.data = body:sub(r.data_off)
    if r.service == 0x0E or r.service == 0x10 then
        if r.path_attribute then
            r.attribute = r.path_attribute
        elseif #r.data >= 1 then
            r.attribute, r.attr_off = r.data:byte(1), r.data_off
        end
    end
    return r
end

-- The request an explicit response answers (decode.rs PendingRequest).
local function pending_of(r)
    return { service = r.service, class = r.class, instance = r.instance, attribute = r.attribute }
end

local function request_text(r)
    local target = string.format("%s inst %d", class_text(r.class), r.instance)
    local service = service_text(r.service)
    local suffix = r.cip_path and " (CIP path)" or ""
    local data = r.data
    if r.cip_path and r.path_attribute then
        if (r.service == 0x0E or r.service == 0x10) and r.path_attribute <= 255 then
            data = string.char(r.path_attribute) .. data
        else
            local d = #data > 0 and (" data " .. hex(data)) or ""
            return string.format("%s %s attr %d%s%s", service, target, r.path_attribute, d, suffix)
        end
    end
    local t
    if r.service == 0x0E then
        if #data == 1 then
            t = string.format("%s %s %s", service, target, attribute_text(r.class, r.instance, data:byte(1)))
        else
            t = string.format("%s %s data %s", service, target, hex(data))
        end
    elseif r.service == 0x10 then
        if #data >= 1 then
            local a = data:byte(1)
            t = string.format("%s %s %s = %s", service, target, attribute_text(r.class, r.instance, a),
                value_text(r.class, r.instance, a, data:sub(2)))
        else
            t = string.format("%s %s (no attribute)", service, target)
        end
    elseif r.service == 0x4B and r.class == 0x03 then
        if #data == 2 and bit.band(data:byte(2), 0xC0) == 0 then
            t = string.format("%s %s: choice %s, allocator MAC %d", service, target, choice_text(data:byte(1)), data:byte(2))
        else
            t = string.format("%s %s: malformed: %s", service, target, hex(data))
        end
    elseif r.service == 0x4C and r.class == 0x03 then
        if #data == 1 then
            t = string.format("%s %s: choice %s", service, target, choice_text(data:byte(1)))
        else
            t = string.format("%s %s: malformed: %s", service, target, hex(data))
        end
    elseif #data == 0 then
        t = string.format("%s %s", service, target)
    else
        t = string.format("%s %s data %s", service, target, hex(data))
    end
    return t .. suffix
end

local function response_text(body, p)
    if #body < 1 then return "malformed response (message truncated: needs 1 bytes, has 0): " end
    local sb = body:byte(1)
    if bit.band(sb, 0x80) == 0 then
        return "malformed response (expected a response, found a request): " .. hex(body)
    end
    local service = bit.band(sb, 0x7F)
    if service == 0x14 then
        if #body < 2 then return "malformed response (message truncated: needs 2 bytes, has 1): " .. hex(body) end
        return "Error_Response: " .. error_text(body:byte(2), #body >= 3 and body:byte(3) or 0xFF)
    end
    local name = service_text(service)
    local data = body:sub(2)
    if p and p.service ~= service then p = nil end
    if service == 0x0E and p then
        local a = p.attribute or 0
        return string.format("%s response: %s inst %d %s = %s", name, class_text(p.class), p.instance,
            attribute_text(p.class, p.instance, a), value_text(p.class, p.instance, a, data))
    elseif service == 0x10 and p and #data > 0 then
        local a = p.attribute or 0
        return string.format("%s response: success, %s applied = %s", name,
            attribute_text(p.class, p.instance, a), value_text(p.class, p.instance, a, data))
    elseif service == 0x4B then
        if #data == 1 then
            return string.format("%s response: success, message body format %s", name, body_format_text(data:byte(1)))
        end
        return string.format("%s response: success, data %s", name, hex(data))
    elseif #data == 0 then
        return name .. " response: success"
    end
    return string.format("%s response: success, data %s", name, hex(data))
end

---------------------------------------------------------------------------------------------
-- First-pass state (reset by init): per device MAC, what later frames need (decode.rs Device).

local devices       -- [mac] = device state
local frame_ctx     -- [frame number] = what the frame needs to be dissected again

local function new_series() return { buf = nil, next = nil, frames = nil, ctxs = nil } end

local function device(mac)
    local d = devices[mac]
    if not d then
        d = {
            body_format = nil, pending = nil,
            request_rx = new_series(), response_rx = new_series(),
            produced = nil, consumed = nil,
            poll_response = new_series(), poll_command = new_series(),
            other = { [12] = { size = nil, io = new_series() }, [13] = { size = nil, io = new_series() },
                      [14] = { size = nil, io = new_series() } },
        }
        devices[mac] = d
    end
    return d
end

local function reset_state()
    devices = {}
    frame_ctx = {}
end
reset_state()
dnetx.init = reset_state

local function reset(rx)
    rx.buf, rx.next, rx.frames, rx.ctxs, rx.last = nil, nil, nil, nil, nil
end

local function next_count(c) return (c + 1) % 64 end

-- Breaches of the fragmentation protocol (protocol §4; decode/fragments.rs FragmentViolation):
-- " (protocol error: <what>; <what the receiver does>)", exactly as the Rust decoder writes it.
local function skipped_text(expected, got)
    local ahead = (got - expected) % 64
    if ahead == 1 then return string.format("fragment #%d was missed", expected) end
    if ahead >= 2 and ahead <= 31 then
        return string.format("fragments #%d to #%d were missed", expected, (got - 1) % 64)
    end
    return "a fragment repeated or out of order"
end

local function protocol_error(what, consequence)
    return string.format(" (protocol error: %s; %s)", what, consequence)
end

local function first_count_error(count)
    return protocol_error(string.format("first fragment with count %d, where a series begins with count 0", count), "fragment dropped")
end

local function no_first_error(kind, count)
    return protocol_error(string.format("%s fragment #%d without a first fragment", frag_type_names[kind], count), "fragment dropped")
end

local function sequence_error(expected, got)
    return protocol_error(string.format("fragment #%d where #%d was due: %s", got, expected, skipped_text(expected, got)), "series dropped")
end

local function unfinished_error(expected)
    return protocol_error(string.format("a new series began while fragment #%d of the one in progress was due: the rest of that series was missed", expected), "unfinished series dropped")
end

local ACK_IN_IO_ERROR = protocol_error("acknowledge-type fragment, which I/O fragmentation does not have", "series dropped")

-- Explicit reassembly of one direction (protocol §4.1; devicenet ExplicitReassembler).
-- `data` is the frame's whole CAN data; returns status, reason.
local MAX_EXPLICIT = 1024
local function explicit_receive(rx, data, number, ctx)
    local fb = data:byte(2)
    local kind, count = bit.rshift(fb, 6), bit.band(fb, 0x3F)
    local body = data:sub(3)
    if kind == 3 then return "dropped", "unexpected acknowledge" end
    if kind == 0 then
        reset(rx)
        if count ~= 0 and count ~= 0x3F then
            return "error", first_count_error(count)
        end
        rx.buf = string.char(bit.band(data:byte(1), 0x7F)) .. body
        rx.frames, rx.ctxs = { number }, { ctx }
        rx.last = fb
        if count == 0x3F then return "complete" end
        rx.next = next_count(count)
        return "ack"
    end
    if rx.next ~= nil and count == rx.next then
        if #rx.buf + #body > MAX_EXPLICIT then
            reset(rx)
            return "dropped", "message too long"
        end
        rx.buf = rx.buf .. body
        rx.frames[#rx.frames + 1] = number
        rx.ctxs[#rx.ctxs + 1] = ctx
        rx.last = fb
        if kind == 2 then rx.next = nil return "complete" end
        rx.next = next_count(count)
        return "ack"
    end
    if rx.last == fb then return "repeated" end
    if rx.next ~= nil then
        local expected = rx.next
        reset(rx)
        return "error", sequence_error(expected, count)
    end
    return "error", no_first_error(kind, count)
end

-- Explicit channel of a Group 2 message (decode.rs Channel).
local CH_REQUEST, CH_G2ONLY, CH_RESPONSE = 1, 2, 3

-- The first-pass work on a whole explicit body: remembers requests, learns sizes and body
-- format from responses. Fills ctx.fmt/ctx.assumed (requests) or ctx.pending (responses).
local function learn_body(d, body, channel, ctx)
    if channel ~= CH_RESPONSE then
        local fmt, assumed
        if channel == CH_G2ONLY then fmt, assumed = 0, false
        elseif d.body_format ~= nil then fmt, assumed = d.body_format, false
        else fmt, assumed = 0, true end
        ctx.fmt, ctx.assumed = fmt, assumed
        local r = parse_request(body, fmt)
        d.pending = r and pending_of(r) or nil
    else
        local p = d.pending
        d.pending = nil
        ctx.pending = p
        if p and #body >= 1 and bit.band(body:byte(1), 0x80) ~= 0 and bit.band(body:byte(1), 0x7F) ~= 0x14 then
            local data = body:sub(2)
            local u16 = #data == 2 and le16(data, 1) or nil
            if p.service == 0x0E and p.class == 0x05 and p.attribute == 7 and p.instance == 2 then
                d.produced = u16
            elseif p.service == 0x0E and p.class == 0x05 and p.attribute == 8 and p.instance == 2 then
                d.consumed = u16
            elseif p.service == 0x0E and p.class == 0x05 and p.attribute == 7 and p.instance >= 3 and p.instance <= 5 then
                local msg = ({ [3] = 14, [4] = 13, [5] = 12 })[p.instance]
                d.other[msg].size = u16
            elseif p.service == 0x4B and p.class == 0x03 and #data == 1 then
                d.body_format = bit.band(data:byte(1), 0x0F)
            end
        end
    end
end

-- Heartbeat / shutdown (protocol §3.7, §II.5): a response whose service is 0xCD/0xCE.
local function is_broadcast(data)
    local s = data:byte(2)
    return #data >= 2 and bit.band(data:byte(1), 0x80) == 0 and (s == 0xCD or s == 0xCE)
end

local function explicit_first_pass(mac, data, channel, number)
    local ctx = { kind = "explicit" }
    local d = device(mac)
    if #data == 0 then return ctx end
    local hdr = data:byte(1)
    if bit.band(hdr, 0x80) == 0 then
        if channel == CH_RESPONSE and is_broadcast(data) then return ctx end
        if channel ~= CH_RESPONSE then
            reset(d.request_rx)
            reset(d.response_rx)
        else
            reset(d.response_rx)
        end
        learn_body(d, data:sub(2), channel, ctx)
        return ctx
    end
    if #data < 2 then return ctx end
    if bit.rshift(data:byte(2), 6) == 3 then return ctx end -- an acknowledge: nothing to learn
    local rx = channel == CH_RESPONSE and d.response_rx or d.request_rx
    local status, why = explicit_receive(rx, data, number, ctx)
    ctx.status, ctx.why = status, why
    if status == "complete" then
        ctx.reassembled = rx.buf
        ctx.frames = rx.frames
        for _, c in ipairs(rx.ctxs) do c.reassembled_in = number end
        reset(rx)
        learn_body(d, ctx.reassembled:sub(2), channel, ctx)
    end
    return ctx
end

-- I/O data on a connection of `size` bytes (protocol §4.2; decode.rs io_data).
local MAX_IO = 448
local function io_first_pass(series, size, data, number)
    local ctx = { kind = "io" }
    local fragmented
    if size ~= nil then
        fragmented = size > 8
    else
        -- decode/fragments.rs IoSeries::looks_fragmented
        local b = data:byte(1)
        if b == nil then
            fragmented = false
        elseif series.proven then
            local kind = bit.rshift(b, 6)
            if kind == 0 then fragmented = #data == 8 or bit.band(b, 0x3F) == 0x3F
            elseif kind == 1 then fragmented = #data == 8
            else fragmented = true end
        elseif series.next == nil then
            fragmented = b == 0 and #data == 8
        else
            local kind = bit.rshift(b, 6)
            if kind == 0 then fragmented = false
            else fragmented = (bit.band(b, 0x3F) == series.next and kind ~= 3) or #data < 8 end
        end
        ctx.inferred = fragmented
    end
    ctx.fragmented = fragmented
    if not fragmented then
        reset(series)
        return ctx
    end
    local b = data:byte(1) or 0
    local kind, count = bit.rshift(b, 6), bit.band(b, 0x3F)
    local body = data:sub(2)
    if kind == 3 then
        reset(series)
        ctx.error = ACK_IN_IO_ERROR
        return ctx
    end
    if kind == 0 then
        -- A first fragment restarts the series (protocol §4.2): one still in progress lost its end.
        if series.next ~= nil then ctx.unfinished = unfinished_error(series.next) end
        reset(series)
        if count == 0x3F then
            ctx.reassembled, ctx.frames = body, { number }
            return ctx
        end
        if count ~= 0 then
            ctx.error = first_count_error(count)
            return ctx
        end
        series.buf, series.frames, series.ctxs = body, { number }, { ctx }
        series.next = 1
        return ctx
    end
    if series.next == nil then
        ctx.error = no_first_error(kind, count)
        return ctx
    end
    if count ~= series.next then
        ctx.error = sequence_error(series.next, count)
        reset(series)
        return ctx
    end
    if #series.buf + #body > MAX_IO then
        reset(series)
        ctx.why = string.format("fragment series exceeds %d bytes", MAX_IO)
        return ctx
    end
    series.buf = series.buf .. body
    series.frames[#series.frames + 1] = number
    series.ctxs[#series.ctxs + 1] = ctx
    if kind == 2 then
        ctx.reassembled, ctx.frames = series.buf, series.frames
        for _, c in ipairs(series.ctxs) do c.reassembled_in = number end
        reset(series)
        -- A whole series of several fragments: the connection is fragmented from now on.
        if size == nil then series.proven = true end
    else
        series.next = next_count(count)
    end
    return ctx
end

---------------------------------------------------------------------------------------------
-- The identifier (protocol §1.1)

local function split_id(id)
    if id < 0x400 then
        return 1, bit.rshift(id, 6), bit.band(id, 0x3F)
    elseif id < 0x600 then
        return 2, bit.band(id, 7), bit.band(bit.rshift(id, 3), 0x3F)
    elseif id < 0x7C0 then
        return 3, bit.band(bit.rshift(id, 6), 7), bit.band(id, 0x3F)
    elseif id < 0x7F0 then
        return 4, id - 0x7C0, nil
    end
    return nil
end

---------------------------------------------------------------------------------------------
-- Tree and text

-- Adds a request body's items under `t` (body = tvb range of the service byte onward).
local function tree_request(t, brange, body, r)
    t:add(F.rr, brange(0, 1))
    t:add(F.service, brange(0, 1))
    t:add(F.service_name, brange(0, 1), service_text(r.service))
    if r.cip_path then
        t:add(F.path_size, brange(1, 1))
        if r.path_len > 0 then t:add(F.path, brange(r.path_off - 1, r.path_len)) end
    end
    t:add_le(F.class, brange(r.cls_off - 1, r.cls_w), r.class)
    t:add_le(F.instance, brange(r.inst_off - 1, r.inst_w), r.instance)
    if r.attribute then
        local ar = r.attr_off and brange(r.attr_off - 1, 1) or brange(r.pattr_off - 1, r.pattr_w)
        local ai = t:add(F.attribute, ar, r.attribute)
        local an = attribute_name(r.class, r.instance, r.attribute)
        if an then
            ai:append_text(" (" .. an .. ")")
            t:add(F.attribute_name, ar, an):set_generated()
        end
    end
    local doff = r.data_off - 1
    if r.attr_off then doff = doff + 1 end
    local rest = #body - doff
    if r.service == 0x4B and r.class == 0x03 and rest >= 1 then
        local ci = t:add(F.alloc_choice, brange(doff, 1))
        ci:append_text(" (" .. choice_text(body:byte(doff + 1)) .. ")")
        for _, f in ipairs(choice_fields) do ci:add(f, brange(doff, 1)) end
        if rest >= 2 then t:add(F.allocator, brange(doff + 1, 1)) end
    elseif r.service == 0x4C and r.class == 0x03 and rest >= 1 then
        local ci = t:add(F.release_choice, brange(doff, 1))
        ci:append_text(" (" .. choice_text(body:byte(doff + 1)) .. ")")
        for _, f in ipairs(choice_fields) do ci:add(f, brange(doff, 1)) end
    elseif rest > 0 then
        local di = t:add(F.data, brange(doff, rest))
        if r.service == 0x10 and r.attribute then
            t:add(F.value, brange(doff, rest), value_text(r.class, r.instance, r.attribute, body:sub(doff + 1)))
        end
    end
end

local function tree_response(t, brange, body, p, pinfo)
    if #body < 1 then return end
    t:add(F.rr, brange(0, 1))
    t:add(F.service, brange(0, 1))
    local service = bit.band(body:byte(1), 0x7F)
    t:add(F.service_name, brange(0, 1), service_text(service))
    if bit.band(body:byte(1), 0x80) == 0 then return end
    if service == 0x14 then
        if #body >= 2 then
            local gi = t:add(F.err_general, brange(1, 1))
            gi:add_proto_expert_info(ef_error, "Error response: " .. general_text(body:byte(2)))
        end
        if #body >= 3 then t:add(F.err_additional, brange(2, 1)) end
        return
    end
    if p and p.service == service then
        local ci = t:add(F.class, p.class):set_generated()
        t:add(F.instance, p.instance):set_generated()
        if p.attribute then
            local ai = t:add(F.attribute, p.attribute)
            ai:set_generated()
            local an = attribute_name(p.class, p.instance, p.attribute)
            if an then ai:append_text(" (" .. an .. ")") t:add(F.attribute_name, an):set_generated() end
        end
    end
    if #body > 1 then
        if service == 0x4B and #body == 2 then
            t:add(F.body_format, brange(1, 1))
        else
            t:add(F.data, brange(1, #body - 1))
            if p and p.service == service and p.attribute and (service == 0x0E or service == 0x10) then
                t:add(F.value, brange(1, #body - 1), value_text(p.class, p.instance, p.attribute, body:sub(2)))
            end
        end
    end
end

-- The text and tree of a whole explicit body in `brange` (a TvbRange of it).
local function explicit_body(t, brange, body, channel, ctx, pinfo)
    if channel ~= CH_RESPONSE then
        local note = ctx.assumed and " [body format 8/8 assumed: no Allocate response seen]" or ""
        if ctx.assumed then t:add(F.body_format_assumed, true):set_generated() end
        local r, why = parse_request(body, ctx.fmt or 0)
        if not r then
            t:add_proto_expert_info(ef_malformed, why)
            if ctx.fmt == 4 then return string.format("malformed request (%s): %s", why, hex(body)) end
            return string.format("malformed request (%s)%s: %s", why, note, hex(body))
        end
        tree_request(t, brange, body, r)
        if r.cip_path then return request_text(r) end
        return request_text(r) .. note
    end
    tree_response(t, brange, body, ctx.pending, pinfo)
    return response_text(body, ctx.pending)
end

local function heartbeat(t, tvb, mac, data)
    local hm = bit.band(data:byte(1), 0x3F)
    local body = data:sub(2)
    local name, fields
    t:add(F.hdr, tvb(0, 1))
    t:add(F.service, tvb(1, 1))
    if body:byte(1) == 0xCD and #body == 7 then
        name = "Device Heartbeat"
        local state, flags = body:byte(4), body:byte(5)
        local set = {}
        for _, f in ipairs({ { 1, "DF device fault" }, { 2, "UF user fault" }, { 4, "SF system fault" }, { 8, "EV event" } }) do
            if bit.band(flags, f[1]) ~= 0 then set[#set + 1] = f[2] end
        end
        local reserved = bit.band(flags, 0xF0) ~= 0 and string.format(", reserved bits 0x%02X set", bit.band(flags, 0xF0)) or ""
        local sn = ({ [0] = "non-existent", "self-testing", "standby", "operational", "major recoverable fault", "major unrecoverable fault" })[state] or "unknown state"
        fields = string.format("Identity instance %d, state %d (%s), flags 0x%02X (%s)%s, configuration consistency value 0x%04X",
            le16(body, 2), state, sn, flags, #set == 0 and "none" or table.concat(set, ", "), reserved, le16(body, 6))
        t:add_le(F.hb_instance, tvb(2, 2))
        t:add(F.hb_state, tvb(4, 1))
        local fi = t:add(F.hb_flags, tvb(5, 1))
        fi:add(F.hb_df, tvb(5, 1)) fi:add(F.hb_uf, tvb(5, 1)) fi:add(F.hb_sf, tvb(5, 1)) fi:add(F.hb_ev, tvb(5, 1))
        t:add_le(F.hb_ccv, tvb(6, 2))
    elseif body:byte(1) == 0xCE and #body == 7 then
        name = "Device Shutdown"
        fields = string.format("class 0x%04X instance %d code 0x%04X", le16(body, 2), le16(body, 4), le16(body, 6))
        t:add_le(F.sd_class, tvb(2, 2))
        t:add_le(F.sd_instance, tvb(4, 2))
        t:add_le(F.sd_code, tvb(6, 2))
    else
        local n = body:byte(1) == 0xCD and "Device Heartbeat" or "Device Shutdown"
        t:add_proto_expert_info(ef_malformed, "a heartbeat or shutdown has exactly 8 bytes")
        return string.format("%s from MAC %d, malformed: %d bytes, a heartbeat or shutdown has exactly 8: %s", n, mac, #data, hex(data))
    end
    local warning = ""
    if hm ~= mac then
        warning = string.format(" (warning: header MAC %d is not the identifier's MAC %d; a heartbeat or shutdown carries the sender's own MAC)", hm, mac)
    end
    return string.format("%s from MAC %d: %s%s", name, mac, fields, warning)
end

local function add_fragment_list(t, tvb, ctx)
    if ctx.frames then
        for _, n in ipairs(ctx.frames) do t:add(F.fragment, tvb(0, 0), n):set_generated() end
    end
end

-- Explicit frame: returns summary, message (or nil).
local function explicit_frame(t, tvb, pinfo, mac, data, channel, ctx)
    local what = ({ "explicit request to MAC", "Group 2 Only unconnected request to MAC", "explicit response from MAC" })[channel]
    if #data == 0 then return string.format("%s %d: empty frame", what, mac) end
    local hdr = data:byte(1)
    local frag, xid, hmac = bit.band(hdr, 0x80) ~= 0, bit.band(hdr, 0x40) ~= 0, bit.band(hdr, 0x3F)
    local head = string.format("%s %d [%smaster MAC %d]", what, mac, xid and "XID 1, " or "", hmac)
    if not frag and channel == CH_RESPONSE and is_broadcast(data) then
        return heartbeat(t, tvb, mac, data)
    end
    local hi = t:add(F.hdr, tvb(0, 1))
    hi:add(F.hdr_frag, tvb(0, 1))
    hi:add(F.hdr_xid, tvb(0, 1))
    hi:add(F.hdr_mac, tvb(0, 1))
    if not frag then
        return head .. " " .. explicit_body(t, tvb(1), data:sub(2), channel, ctx, pinfo)
    end
    if #data < 2 then
        t:add_proto_expert_info(ef_malformed, "fragment without fragmentation byte")
        return string.format("%s malformed fragment (message truncated: needs 2 bytes, has %d): %s", head, #data, hex(data))
    end
    local fb = data:byte(2)
    local kind, count = bit.rshift(fb, 6), bit.band(fb, 0x3F)
    t:add(F.frag_type, tvb(1, 1))
    t:add(F.frag_count, tvb(1, 1))
    if kind == 3 then
        local status
        if #data >= 3 then
            local s = data:byte(3)
            t:add(F.frag_ack_status, tvb(2, 1))
            status = s == 0 and "success (0x00)" or s == 1 and "too much data (0x01)" or string.format("reserved (0x%02X)", s)
        else
            status = "no status"
        end
        return string.format("%s fragment ack #%d status %s", head, count, status)
    end
    if #data > 2 then t:add(F.frag_data, tvb(2)) end
    local summary = string.format("%s fragment %s #%d (%d body bytes): %s", head, frag_type_names[kind], count, #data - 2, hex(data, 3))
    if ctx.reassembled_in and not ctx.reassembled then
        t:add(F.reassembled_in, tvb(0, 0), ctx.reassembled_in):set_generated()
    end
    if ctx.status == "error" then
        t:add(F.frag_note, tvb(1, 1), ctx.why:sub(2)):add_proto_expert_info(ef_protocol, ctx.why:sub(2))
        return summary .. ctx.why
    elseif ctx.status == "dropped" then
        t:add(F.frag_note, tvb(1, 1), "dropped: " .. (ctx.why or "")):add_proto_expert_info(ef_dropped, "dropped: " .. (ctx.why or ""))
        return summary .. " (dropped: " .. (ctx.why or "") .. ")"
    elseif ctx.status == "repeated" then
        t:add(F.frag_note, tvb(1, 1), "repeated")
        return summary .. " (repeated)"
    elseif ctx.status == "complete" and ctx.reassembled then
        local whole = ctx.reassembled
        local rtvb = ByteArray.new(hex(whole)):tvb("Reassembled DeviceNet explicit message")
        local rt = t:add(dnetx, rtvb(), string.format("Reassembled explicit message (%d bytes)", #whole))
        rt:add(F.reassembled, rtvb())
        rt:add(F.reassembled_len, rtvb(), #whole):set_generated()
        add_fragment_list(rt, rtvb, ctx)
        local rh = rt:add(F.hdr, rtvb(0, 1))
        rh:add(F.hdr_frag, rtvb(0, 1)) rh:add(F.hdr_xid, rtvb(0, 1)) rh:add(F.hdr_mac, rtvb(0, 1))
        local text = explicit_body(rt, rtvb(1), whole:sub(2), channel, ctx, pinfo)
        return summary, string.format("reassembled %d bytes: %s", #whole, text)
    end
    return summary
end

local function io_frame(t, tvb, who, data, ctx)
    if not ctx.fragmented then
        if #data == 0 then return who .. ": no data (idle)" end
        t:add(F.io_data, tvb())
        t:add(F.io_len, tvb(), #data):set_generated()
        return who .. ": " .. data_text(data)
    end
    local b = data:byte(1)
    local kind, count = 0, 0
    if b then
        kind, count = bit.rshift(b, 6), bit.band(b, 0x3F)
        t:add(F.frag_type, tvb(0, 1))
        t:add(F.frag_count, tvb(0, 1))
    end
    if #data > 1 then t:add(F.frag_data, tvb(1)) end
    local inferred = ""
    if ctx.inferred then
        inferred = ", size inferred from fragment bytes"
        t:add(F.io_inferred, true):set_generated()
    end
    local single = (kind == 0 and count == 0x3F) and " (a one-frame series: the whole message)" or ""
    local summary = string.format("%s: I/O fragment %s #%d%s%s: %s", who, frag_type_names[kind], count, single, inferred, hex(data, 2))
    if ctx.reassembled_in and not ctx.reassembled then
        t:add(F.reassembled_in, tvb(0, 0), ctx.reassembled_in):set_generated()
    end
    for _, e in ipairs({ ctx.unfinished or false, ctx.error or false }) do
        if e then
            local note = e:sub(2)
            t:add(F.frag_note, tvb(0, 1), note):add_proto_expert_info(ef_protocol, note)
            summary = summary .. e
        end
    end
    if ctx.why then
        t:add(F.frag_note, tvb(0, 1), "dropped: " .. ctx.why):add_proto_expert_info(ef_dropped, "dropped: " .. ctx.why)
        return summary .. " (dropped: " .. ctx.why .. ")"
    end
    if ctx.error then return summary end
    if ctx.reassembled then
        local whole = ctx.reassembled
        local rtvb = ByteArray.new(hex(whole)):tvb("Reassembled DeviceNet I/O message")
        local rt = t:add(dnetx, rtvb(), string.format("Reassembled I/O message (%d bytes)", #whole))
        rt:add(F.reassembled, rtvb())
        rt:add(F.reassembled_len, rtvb(), #whole):set_generated()
        rt:add(F.io_data, rtvb())
        rt:add(F.io_len, rtvb(), #whole):set_generated()
        add_fragment_list(rt, rtvb, ctx)
        return summary, string.format("%s, %d bytes: %s", who, #whole, hex(whole))
    end
    return summary
end

local function dupmac(t, tvb, mac, data)
    if #data ~= 7 then
        t:add_proto_expert_info(ef_malformed, "a duplicate MAC ID check has 7 bytes")
        return string.format("malformed duplicate MAC ID check for MAC %d (wrong length: the message has 7 bytes, got %d): %s", mac, #data, hex(data))
    end
    t:add(F.dup_rr, tvb(0, 1))
    t:add(F.dup_port, tvb(0, 1))
    t:add_le(F.vendor, tvb(1, 2))
    t:add_le(F.serial, tvb(3, 4))
    return string.format("duplicate MAC ID check %s for MAC %d: port %d, vendor 0x%04X, serial 0x%08X",
        bit.band(data:byte(1), 0x80) ~= 0 and "response" or "request", mac, bit.band(data:byte(1), 0x7F),
        le16(data, 2), le32(data, 4))
end

local function group3(t, tvb, msg, src, data)
    local s = data:byte(2)
    local function hdr()
        local hi = t:add(F.hdr, tvb(0, 1))
        hi:add(F.hdr_frag, tvb(0, 1)) hi:add(F.hdr_xid, tvb(0, 1)) hi:add(F.hdr_mac, tvb(0, 1))
        t:add(F.rr, tvb(1, 1))
        t:add(F.service, tvb(1, 1))
        t:add(F.service_name, tvb(1, 1), service_text(bit.band(s, 0x7F)))
    end
    local dst = data:byte(1) and bit.band(data:byte(1), 0x3F)
    if msg == 6 then
        if s == 0x4B and #data == 4 then
            hdr()
            t:add(F.dst, tvb(0, 1), dst)
            t:add(F.body_format, tvb(2, 1))
            t:add(F.ucmm_group, tvb(3, 1))
            t:add(F.ucmm_src_msgid, tvb(3, 1))
            local g = bit.rshift(data:byte(4), 4)
            return string.format("UCMM Open Explicit Messaging Connection request from MAC %d to MAC %d: body format %s, group select %s, source message ID %d",
                src, dst, body_format_text(bit.band(data:byte(3), 0x0F)), group_select_names[g] or string.format("reserved (%d)", g), bit.band(data:byte(4), 0x0F))
        elseif s == 0x4C and #data == 4 then
            hdr()
            t:add(F.dst, tvb(0, 1), dst)
            t:add_le(F.conn_instance, tvb(2, 2))
            return string.format("UCMM Close Connection request from MAC %d to MAC %d: connection instance %d", src, dst, le16(data, 3))
        end
        return string.format("UCMM request from MAC %d: %s", src, hex(data))
    elseif msg == 5 then
        if s == 0xCB and #data == 6 then
            hdr()
            t:add(F.dst, tvb(0, 1), dst)
            t:add(F.body_format, tvb(2, 1))
            t:add(F.ucmm_dst_msgid, tvb(3, 1))
            t:add(F.ucmm_src_msgid, tvb(3, 1))
            t:add_le(F.conn_instance, tvb(4, 2))
            return string.format("UCMM Open response from MAC %d to MAC %d: body format %s, connection instance %d",
                src, dst, body_format_text(bit.band(data:byte(3), 0x0F)), le16(data, 5))
        elseif s == 0xCC and #data == 2 then
            hdr()
            t:add(F.dst, tvb(0, 1), dst)
            return string.format("UCMM Close response from MAC %d to MAC %d", src, dst)
        elseif s == 0x94 and #data >= 3 then
            hdr()
            t:add(F.err_general, tvb(2, 1))
            if #data >= 4 then t:add(F.err_additional, tvb(3, 1)) end
            return string.format("UCMM error response from MAC %d: %s", src, error_text(data:byte(3), #data >= 4 and data:byte(4) or 0xFF))
        end
        return string.format("UCMM response from MAC %d: %s", src, hex(data))
    end
    return string.format("G3 message %d from MAC %d (dynamic connection): %s", msg, src, hex(data))
end

-- Group 4: the Offline Connection Set (protocol §3.8, §II.6).
local function group4(t, tvb, msg, data)
    local SET = "Offline Connection Set:"
    local n = #data
    local function selector(i)
        t:add(F.off_match, tvb(i, 1))
        t:add(F.off_value, tvb(i, 1))
        local b = data:byte(i + 1)
        local m = bit.band(b, 0x40) ~= 0
        return string.format("match %d (%s), value %d", m and 1 or 0, m and "exact MAC ID" or "mask", bit.band(b, 0x3F))
    end
    local function service()
        t:add(F.rr, tvb(1, 1))
        t:add(F.service, tvb(1, 1))
    end
    local function key(i)
        t:add_le(F.vendor, tvb(i, 2))
        t:add_le(F.serial, tvb(i + 2, 4))
        return string.format("vendor 0x%04X, serial 0x%08X", le16(data, i + 1), le32(data, i + 3))
    end
    local s = data:byte(2)
    if msg == 0x2D then
        if s == 0x4B and n == 3 and data:byte(3) <= 6 and bit.band(data:byte(1), 0x80) == 0 then
            service()
            local sel = selector(0)
            t:add(F.off_delay, tvb(2, 1))
            return string.format("%s Who request (%s), time-delay byte offset %d", SET, sel, data:byte(3))
        elseif s == 0x4C and n == 2 then
            service()
            return string.format("%s Identify request, multicast (%s)", SET, selector(0))
        elseif s == 0x4C and n == 8 and data:byte(1) == 0x3F then
            service()
            local sel = selector(0)
            return string.format("%s Identify request, point-to-point (%s): %s", SET, sel, key(2))
        elseif s == 0x4D and n == 8 and data:byte(1) <= 63 then
            t:add(F.off_new_mac, tvb(0, 1))
            service()
            return string.format("%s Change MAC ID to %d for %s", SET, data:byte(1), key(2))
        end
    elseif msg == 0x2C then
        if n == 7 then
            t:add(F.off_port, tvb(0, 1))
            return string.format("%s Who response from a faulted node: port %d, %s", SET, data:byte(1), key(1))
        elseif n == 2 and s == 0xCC then
            service()
            return string.format("%s Identify response (%s)", SET, selector(0))
        end
    elseif msg == 0x2F or msg == 0x2E then
        local want = msg == 0x2F and 0x4B or 0xCB
        if n == 8 and s == want and data:byte(1) <= 63 then
            t:add(F.off_client, tvb(0, 1))
            service()
            if msg == 0x2F then
                return string.format("%s ownership request from tool MAC %d: %s", SET, data:byte(1), key(2))
            end
            return string.format("%s ownership response to tool MAC %d: %s", SET, data:byte(1), key(2))
        end
    end
    if msg >= 0x2C then t:add_proto_expert_info(ef_malformed, "unexpected layout for this Group 4 message") end
    return string.format("G4 message 0x%02X: %s", msg, hex(data))
end

---------------------------------------------------------------------------------------------
-- The dissector

-- What the dissector returns: the bytes it took, and at least 1 for a frame without data (a zero
-- would tell the CAN dissector the frame is not DeviceNet and hand it to its heuristics).
local function accepted(tvb)
    return math.max(tvb:len(), 1)
end

function dnetx.dissector(tvb, pinfo, tree)
    local id = pinfo.match_uint
    if id == nil or id == 0 then
        -- Decode As on can.subdissector: the identifier from the CAN layer.
        local f = f_can_id()
        if f then id = f.value end
    end
    if id == nil then return 0 end
    id = bit.band(id, 0x7FF)
    local group, msg, mac = split_id(id)
    pinfo.cols.protocol = "DeviceNet"
    local data = tvb:len() > 0 and tvb:raw(0, tvb:len()) or ""
    local t = tree:add(dnetx, tvb())
    if not group then
        local text = string.format("invalid identifier 0x%03X (0x7F0-0x7FF are not used): %s", id, hex(data))
        t:add_proto_expert_info(ef_malformed, "identifier 0x7F0-0x7FF is not used by DeviceNet")
        t:add(F.summary, tvb(0, 0), text):set_generated()
        pinfo.cols.info:set(text)
        t:append_text(": " .. text)
        return accepted(tvb)
    end

    -- First pass: update the per-device state, remember what this frame needs.
    local ctx = frame_ctx[pinfo.number]
    if ctx == nil then
        if pinfo.visited then
            ctx = {} -- a frame never seen on the first pass (should not happen)
        elseif group == 2 and (msg == 3 or msg == 4 or msg == 6) then
            local channel = msg == 4 and CH_REQUEST or msg == 6 and CH_G2ONLY or CH_RESPONSE
            ctx = explicit_first_pass(mac, data, channel, pinfo.number)
        elseif group == 2 and msg == 5 then
            local d = device(mac)
            ctx = io_first_pass(d.poll_command, d.consumed, data, pinfo.number)
        elseif group == 1 and msg == 15 then
            local d = device(mac)
            ctx = io_first_pass(d.poll_response, d.produced, data, pinfo.number)
        elseif group == 1 and msg >= 12 and msg <= 14 then
            local o = device(mac).other[msg]
            ctx = io_first_pass(o.io, o.size, data, pinfo.number)
        else
            ctx = {}
        end
        frame_ctx[pinfo.number] = ctx
    end

    -- The identifier.
    local it = t:add(dnetx, tvb(0, 0), string.format("Identifier 0x%03X", id))
    it:set_generated()
    it:add(F.group, group):set_generated()
    it:add(F.msgid, msg):set_generated()
    local names = ({ g1_names, g2_names, g3_names, g4_names })[group]
    local mname = names[msg]
    if not mname then
        if group == 1 or group == 3 then mname = "dynamically allocated (UCMM) connection"
        else mname = "reserved" end
    end
    it:add(F.message, mname):set_generated()
    if mac then
        it:add(F.mac, mac):set_generated()
        local src = group ~= 2 or msg == 0 or msg == 3 or msg == 7
        if group == 2 and msg == 1 then
            it:append_text(string.format(", %s, message ID %d, group MAC %d", group_names[group], msg, mac))
        else
            it:add(src and F.src or F.dst, mac):set_generated()
            it:append_text(string.format(", %s, message ID %d, %s MAC %d", group_names[group], msg, src and "source" or "destination", mac))
        end
    else
        it:append_text(string.format(", %s, message ID 0x%02X", group_names[group], msg))
    end
    it:append_text(": " .. mname)

    -- Source and Destination columns: the MAC IDs the identifier and the explicit header name.
    local hdr_mac = #data >= 1 and bit.band(data:byte(1), 0x3F) or nil
    local col_src, col_dst
    if group == 1 or group == 3 then
        col_src = mac
        if group == 3 and (msg == 5 or msg == 6) then col_dst = hdr_mac end
    elseif group == 2 then
        if msg == 0 or msg == 7 then col_src = mac
        elseif msg == 3 then col_src, col_dst = mac, hdr_mac
        elseif msg == 4 or msg == 6 then col_src, col_dst = hdr_mac, mac
        elseif msg == 2 or msg == 5 then col_dst = mac
        end
    end
    if col_src then pinfo.cols.src:set("MAC " .. col_src) end
    if col_dst then pinfo.cols.dst:set("MAC " .. col_dst) end

    local summary, message
    if group == 1 then
        local who = ({ [12] = "multicast poll response", [13] = "change-of-state/cyclic data",
                       [14] = "bit-strobe response", [15] = "poll response" })[msg]
        if who then
            summary, message = io_frame(t, tvb, string.format("%s from MAC %d", who, mac), data, ctx)
        else
            summary = string.format("G1 message %d from MAC %d (dynamic connection): %s", msg, mac, hex(data))
        end
    elseif group == 2 then
        if msg == 7 then
            summary = dupmac(t, tvb, mac, data)
        elseif msg == 3 or msg == 4 or msg == 6 then
            local channel = msg == 4 and CH_REQUEST or msg == 6 and CH_G2ONLY or CH_RESPONSE
            summary, message = explicit_frame(t, tvb, pinfo, mac, data, channel, ctx)
        elseif msg == 5 then
            summary, message = io_frame(t, tvb, string.format("poll command to MAC %d", mac), data, ctx)
        else
            if #data > 0 then t:add(F.io_data, tvb()) end
            if msg == 0 then
                summary = string.format("bit-strobe command from master MAC %d: %s", mac, data_text(data))
            elseif msg == 1 then
                summary = string.format("multicast poll command, group MAC %d: %s", mac, data_text(data))
            else
                summary = string.format("change-of-state/cyclic acknowledge to MAC %d: %s", mac, data_text(data))
            end
        end
    elseif group == 3 then
        summary = group3(t, tvb, msg, mac, data)
    else
        summary = group4(t, tvb, msg, data)
    end

    local text = summary
    if message then text = summary .. " => " .. message end
    t:add(F.summary, tvb(0, 0), text):set_generated()
    t:append_text(": " .. text)
    pinfo.cols.info:set(text)
    return accepted(tvb)
end

-- Every 11-bit identifier DeviceNet uses (protocol §1.1: 0x7F0-0x7FF are invalid, shown as such).
DissectorTable.get("can.id"):add("0-2047", dnetx)
-- And Decode As... > CAN next level dissector.
local subdissector = DissectorTable.get("can.subdissector")
if subdissector and subdissector.add_for_decode_as then subdissector:add_for_decode_as(dnetx) end
