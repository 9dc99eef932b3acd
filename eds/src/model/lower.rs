//! Lowering a raw file to the typed model: the rules are in the [parent module](super).

use super::*;

/// Lowers a raw file to the typed model, with the problems found on the way.
pub(super) fn lower(raw: &RawEds) -> (Eds, Vec<Diagnostic>) {
    let mut lower = Lower { diagnostics: Vec::new() };
    let eds = lower.eds(raw);
    (eds, lower.diagnostics)
}

/// CIP sections this model does not type but which are standard, so not worth a warning.
const STANDARD_SECTIONS: &[&str] = &[
    "assembly",
    "connection manager",
    "port",
    "capacity",
    "modular",
    "connection configuration",
    "variant",
    "event enumeration",
    "symbolic translation",
    "internationalization",
];

fn numbered_as(keyword: &str, prefix: &str) -> Option<u32> {
    numbered(keyword).filter(|(p, _)| p == prefix).map(|(_, n)| n)
}

/// Stores `value` in `slot` when there is one; `true` when stored.
fn set<T>(slot: &mut Option<T>, value: Option<T>) -> bool {
    let stored = value.is_some();
    if stored {
        *slot = value;
    }
    stored
}

fn field_text(value: &FieldValue) -> String {
    match value {
        FieldValue::Empty => String::new(),
        FieldValue::Text(t) | FieldValue::Str(t) => t.clone(),
        FieldValue::List(fields) => {
            let inner: Vec<String> = fields.iter().map(|f| field_text(&f.value)).collect();
            format!("{{{}}}", inner.join(", "))
        }
    }
}

struct Lower {
    diagnostics: Vec<Diagnostic>,
}

/// A field of an entry, or the entry's position when the field is missing.
fn field_at(entry: &RawEntry, index: usize) -> (Option<&Field>, Span) {
    match entry.fields.get(index) {
        Some(field) => (Some(field), field.span),
        None => (None, entry.span),
    }
}

impl Lower {
    fn error(&mut self, rule: Rule, span: Span, message: String) {
        self.diagnostics.push(Diagnostic::error(rule, span, message));
    }

    fn warning(&mut self, rule: Rule, span: Span, message: String) {
        self.diagnostics.push(Diagnostic::warning(rule, span, message));
    }

    fn eds(&mut self, raw: &RawEds) -> Eds {
        // Entries of each known section, merged over repeats, first of each keyword only.
        let mut known: HashMap<Known, Vec<&RawEntry>> = HashMap::new();
        let mut first_header: HashMap<String, Span> = HashMap::new();
        let mut seen_keys: HashMap<(Known, String), Span> = HashMap::new();
        let mut eds = Eds::default();
        for section in &raw.sections {
            let normalized = normalize_name(&section.name);
            if let Some(first) = first_header.get(&normalized) {
                self.error(
                    Rule::DuplicateSection,
                    section.span,
                    format!("section [{}] appears again (first at {first})", section.name),
                );
            } else {
                first_header.insert(normalized.clone(), section.span);
            }
            let Some(kind) = Known::of(&section.name) else {
                self.unknown_section(section, &normalized);
                eds.other_sections.push(section.clone());
                continue;
            };
            let entries = known.entry(kind).or_default();
            for entry in &section.entries {
                let key = (kind, entry_key(&entry.keyword));
                if let Some(first) = seen_keys.get(&key) {
                    self.error(
                        Rule::DuplicateEntry,
                        entry.span,
                        format!(
                            "`{}` appears again in [{}] (first at {first}); this one is ignored",
                            entry.keyword,
                            kind.name()
                        ),
                    );
                    continue;
                }
                seen_keys.insert(key, entry.span);
                entries.push(entry);
            }
        }
        let mut take = |kind: Known| known.remove(&kind);
        let (file, device, classification, io_info, param_class, params, enum_par, groups) = (
            take(Known::File),
            take(Known::Device),
            take(Known::Classification),
            take(Known::IoInfo),
            take(Known::ParamClass),
            take(Known::Params),
            take(Known::EnumPar),
            take(Known::Groups),
        );
        eds.file = file.map(|e| self.file(&e));
        eds.device = device.map(|e| self.device(&e));
        eds.classification = classification.map(|e| self.classification(&e));
        eds.io_info = io_info.map(|e| self.io_info(&e));
        eds.param_class = param_class.map(|e| self.param_class(&e));
        eds.params = params.map(|e| self.params(&e));
        eds.enum_par = enum_par.map(|e| self.enum_par(&e));
        eds.groups = groups.map(|e| self.groups(&e));
        eds
    }

    fn unknown_section(&mut self, section: &RawSection, normalized: &str) {
        let standard = STANDARD_SECTIONS.contains(&normalized) || normalized.ends_with(" class");
        if !standard && vendor_prefix(&section.name).is_none() {
            self.warning(
                Rule::UnknownSection,
                section.span,
                format!("unknown section [{}] is kept as is", section.name),
            );
        }
    }

    fn unknown_keyword(&mut self, entry: &RawEntry, section: Known) {
        if entry.vendor_prefix().is_none() {
            self.warning(
                Rule::UnknownKeyword,
                entry.span,
                format!("unknown keyword `{}` in [{}] is kept as is", entry.keyword, section.name()),
            );
        }
    }

    /// The only field of a single-valued entry.
    fn single<'e>(&mut self, entry: &'e RawEntry) -> Option<&'e FieldValue> {
        if entry.fields.len() != 1 {
            self.error(
                Rule::FieldCount,
                entry.span,
                format!("`{}` takes one value, found {} fields", entry.keyword, entry.fields.len()),
            );
            return None;
        }
        Some(&entry.fields[0].value)
    }

    fn single_string(&mut self, entry: &RawEntry) -> Option<String> {
        let value = self.single(entry)?;
        self.string(value, entry.fields[0].span, &entry.keyword)
    }

    fn string(&mut self, value: &FieldValue, span: Span, what: &str) -> Option<String> {
        match value {
            FieldValue::Str(text) => Some(text.clone()),
            FieldValue::Empty => Some(String::new()),
            FieldValue::Text(text) => {
                self.warning(Rule::UnquotedString, span, format!("{what}: string `{text}` should be quoted"));
                Some(text.clone())
            }
            FieldValue::List(_) => {
                self.error(
                    Rule::InvalidValue,
                    span,
                    format!("{what}: expected a string, found a {{ }} group"),
                );
                None
            }
        }
    }

    /// A single value read by `parse`, described as `form` in the error.
    fn single_typed<T>(
        &mut self,
        entry: &RawEntry,
        form: &str,
        parse: impl Fn(&str) -> Option<T>,
    ) -> Option<T> {
        let value = self.single(entry)?;
        let parsed = match value {
            FieldValue::Text(text) => parse(text),
            _ => None,
        };
        if parsed.is_none() {
            self.error(
                Rule::InvalidValue,
                entry.fields[0].span,
                format!("`{}`: expected {form}, found {}", entry.keyword, describe(value)),
            );
        }
        parsed
    }

    fn single_int<T: TryFrom<i128>>(&mut self, entry: &RawEntry, form: &str) -> Option<T> {
        self.single_typed(entry, form, |t| crate::value::parse_int(t).and_then(|v| T::try_from(v).ok()))
    }

    /// Field `index` of `entry` as an integer of type `T`; empty or missing is `None` silently.
    fn int_field<T: TryFrom<i128>>(&mut self, entry: &RawEntry, index: usize, what: &str) -> Option<T> {
        let (field, span) = field_at(entry, index);
        let value = &field?.value;
        match value {
            FieldValue::Empty => None,
            FieldValue::Text(text) => match crate::value::parse_int(text) {
                Some(v) => match T::try_from(v) {
                    Ok(v) => Some(v),
                    Err(_) => {
                        self.error(
                            Rule::InvalidValue,
                            span,
                            format!("`{}` {what}: {v} is out of range", entry.keyword),
                        );
                        None
                    }
                },
                None => {
                    self.error(
                        Rule::InvalidValue,
                        span,
                        format!("`{}` {what}: expected an integer, found {}", entry.keyword, describe(value)),
                    );
                    None
                }
            },
            other => {
                self.error(
                    Rule::InvalidValue,
                    span,
                    format!("`{}` {what}: expected an integer, found {}", entry.keyword, describe(other)),
                );
                None
            }
        }
    }

    fn string_field(&mut self, entry: &RawEntry, index: usize, what: &str) -> String {
        let (field, span) = field_at(entry, index);
        match field {
            Some(field) => {
                self.string(&field.value, span, &format!("`{}` {what}", entry.keyword)).unwrap_or_default()
            }
            None => String::new(),
        }
    }

    fn path_field(&mut self, entry: &RawEntry, index: usize) -> Option<LinkPath> {
        let (field, span) = field_at(entry, index);
        match &field?.value {
            FieldValue::Empty => None,
            FieldValue::Str(text) | FieldValue::Text(text) => Some(LinkPath::parse(text)),
            FieldValue::List(_) => {
                self.error(Rule::InvalidValue, span, format!("`{}` path: expected a string", entry.keyword));
                None
            }
        }
    }

    fn value_field(&mut self, entry: &RawEntry, index: usize, what: &str) -> Option<Value> {
        let (field, span) = field_at(entry, index);
        match &field?.value {
            FieldValue::Empty => None,
            FieldValue::Text(text) => Some(Value::from_text(text)),
            FieldValue::Str(text) => Some(Value::Str(text.clone())),
            FieldValue::List(_) => {
                self.error(
                    Rule::InvalidValue,
                    span,
                    format!("`{}` {what}: unexpected {{ }} group", entry.keyword),
                );
                None
            }
        }
    }

    fn need_fields(&mut self, entry: &RawEntry, need: usize, what: &str) {
        if entry.fields.len() < need {
            self.error(
                Rule::FieldCount,
                entry.span,
                format!("`{}` has {} fields; {what} has {need}", entry.keyword, entry.fields.len()),
            );
        }
    }

    fn file(&mut self, entries: &[&RawEntry]) -> FileInfo {
        let mut info = FileInfo::default();
        for &entry in entries {
            let typed = match entry_key(&entry.keyword).as_str() {
                "desctext" => set(&mut info.desc_text, self.single_string(entry)),
                "createdate" => {
                    set(&mut info.create_date, self.single_typed(entry, "a date MM-DD-YYYY", Date::parse))
                }
                "createtime" => {
                    set(&mut info.create_time, self.single_typed(entry, "a time HH:MM:SS", Time::parse))
                }
                "moddate" => {
                    set(&mut info.mod_date, self.single_typed(entry, "a date MM-DD-YYYY", Date::parse))
                }
                "modtime" => {
                    set(&mut info.mod_time, self.single_typed(entry, "a time HH:MM:SS", Time::parse))
                }
                "revision" => set(
                    &mut info.revision,
                    self.single_typed(entry, "a revision major.minor", Revision::parse),
                ),
                "homeurl" => set(&mut info.home_url, self.single_string(entry)),
                _ => {
                    self.unknown_keyword(entry, Known::File);
                    false
                }
            };
            if !typed {
                info.other.push(entry.clone());
            }
        }
        info
    }

    fn device(&mut self, entries: &[&RawEntry]) -> Device {
        let mut device = Device::default();
        for &entry in entries {
            let typed = match entry_key(&entry.keyword).as_str() {
                "vendcode" => set(&mut device.vend_code, self.single_int(entry, "a vendor ID 0..=65535")),
                "vendname" => set(&mut device.vend_name, self.single_string(entry)),
                "prodtype" => set(&mut device.prod_type, self.single_int(entry, "a device type 0..=65535")),
                "prodtypestr" => set(&mut device.prod_type_str, self.single_string(entry)),
                "prodcode" => set(&mut device.prod_code, self.single_int(entry, "a product code 0..=65535")),
                "majrev" => set(&mut device.maj_rev, self.single_int(entry, "a major revision 0..=255")),
                "minrev" => set(&mut device.min_rev, self.single_int(entry, "a minor revision 0..=255")),
                "prodname" => set(&mut device.prod_name, self.single_string(entry)),
                "catalog" => set(&mut device.catalog, self.single_string(entry)),
                "icon" => set(&mut device.icon, self.single_string(entry)),
                "iconcontents" => set(&mut device.icon_contents, self.single_string(entry)),
                _ => {
                    self.unknown_keyword(entry, Known::Device);
                    false
                }
            };
            if !typed {
                device.other.push(entry.clone());
            }
        }
        device
    }

    fn classification(&mut self, entries: &[&RawEntry]) -> DeviceClassification {
        let mut classification = DeviceClassification::default();
        for &entry in entries {
            match numbered_as(&entry.keyword, "class") {
                Some(n) => {
                    let values = entry.fields.iter().map(|f| field_text(&f.value)).collect();
                    classification.classes.insert(n, values);
                }
                None => {
                    self.unknown_keyword(entry, Known::Classification);
                    classification.other.push(entry.clone());
                }
            }
        }
        classification
    }

    fn io_info(&mut self, entries: &[&RawEntry]) -> IoInfo {
        let mut io = IoInfo::default();
        for &entry in entries {
            let key = entry_key(&entry.keyword);
            let typed = match key.as_str() {
                "default" => set(
                    &mut io.default,
                    self.single_int(entry, "a connection mask 0..=0xFFFF").map(ConnectionMask),
                ),
                "pollinfo" => {
                    io.poll = Some(self.connection_info(entry));
                    true
                }
                "strobeinfo" => {
                    io.strobe = Some(self.connection_info(entry));
                    true
                }
                "cosinfo" => {
                    io.cos = Some(self.connection_info(entry));
                    true
                }
                "cyclicinfo" => {
                    io.cyclic = Some(self.connection_info(entry));
                    true
                }
                _ => match numbered(&entry.keyword) {
                    Some((prefix, n)) if prefix == "input" => {
                        let input = self.io_entry(entry);
                        io.inputs.insert(n, input);
                        true
                    }
                    Some((prefix, n)) if prefix == "output" => {
                        let output = self.io_entry(entry);
                        io.outputs.insert(n, output);
                        true
                    }
                    _ => {
                        self.unknown_keyword(entry, Known::IoInfo);
                        false
                    }
                },
            };
            if !typed {
                io.other.push(entry.clone());
            }
        }
        io
    }

    fn connection_info(&mut self, entry: &RawEntry) -> ConnectionInfo {
        self.need_fields(entry, 3, "a connection entry (mask, default input, default output)");
        ConnectionInfo {
            compatible: self.int_field(entry, 0, "mask").map(ConnectionMask),
            default_input: self.int_field(entry, 1, "default input"),
            default_output: self.int_field(entry, 2, "default output"),
            extra: entry.fields.iter().skip(3).map(|f| f.value.clone()).collect(),
        }
    }

    fn io_entry(&mut self, entry: &RawEntry) -> IoEntry {
        if entry.fields.len() < 3 {
            self.need_fields(entry, 7, "an I/O entry (size, bits, mask, name, path size, path, help)");
        } else if entry.fields.len() < 7 {
            self.warning(
                Rule::FieldCount,
                entry.span,
                format!(
                    "`{}` has {} fields; an I/O entry has 7 (size, bits, mask, name, path size, path, help)",
                    entry.keyword,
                    entry.fields.len()
                ),
            );
        }
        IoEntry {
            size: self.int_field(entry, 0, "size"),
            bits: self.int_field(entry, 1, "bits"),
            mask: self.int_field(entry, 2, "mask").map(ConnectionMask),
            name: self.string_field(entry, 3, "name"),
            path_size: self.int_field(entry, 4, "path size"),
            path: self.path_field(entry, 5),
            help: self.string_field(entry, 6, "help string"),
            extra: entry.fields.iter().skip(7).map(|f| f.value.clone()).collect(),
        }
    }

    fn param_class(&mut self, entries: &[&RawEntry]) -> ParamClass {
        let mut class = ParamClass::default();
        for &entry in entries {
            let typed = match entry_key(&entry.keyword).as_str() {
                "maxinst" => set(&mut class.max_inst, self.single_int(entry, "an instance count")),
                "descriptor" => set(&mut class.descriptor, self.single_int(entry, "a descriptor 0..=0xFFFF")),
                "cfgassembly" => set(&mut class.cfg_assembly, self.single_int(entry, "an assembly instance")),
                _ => {
                    self.unknown_keyword(entry, Known::ParamClass);
                    false
                }
            };
            if !typed {
                class.other.push(entry.clone());
            }
        }
        class
    }

    fn params(&mut self, entries: &[&RawEntry]) -> ParamsSection {
        let mut section = ParamsSection::default();
        for &entry in entries {
            match numbered(&entry.keyword) {
                Some((prefix, n)) if prefix == "param" => {
                    if n == 0 {
                        self.error(
                            Rule::InvalidValue,
                            entry.span,
                            "parameter numbers start at 1 (Param0)".to_string(),
                        );
                    }
                    let param = self.param(entry);
                    section.params.insert(n, param);
                }
                Some((prefix, n)) if prefix == "enum" => {
                    let entries = self.enum_pairs(entry);
                    section.enums.insert(n, entries);
                }
                _ => {
                    self.unknown_keyword(entry, Known::Params);
                    section.other.push(entry.clone());
                }
            }
        }
        section
    }

    fn param(&mut self, entry: &RawEntry) -> Param {
        if entry.fields.len() < Param::FIELD_COUNT {
            self.error(
                Rule::FieldCount,
                entry.span,
                format!(
                    "`{}` has {} fields; a parameter entry has {} (the last ones present are taken as {})",
                    entry.keyword,
                    entry.fields.len(),
                    Param::FIELD_COUNT,
                    Param::FIELD_NAMES[entry.fields.len().clamp(1, Param::FIELD_COUNT) - 1],
                ),
            );
        }
        let names = Param::FIELD_NAMES;
        let data_type: Option<u16> = self.int_field(entry, 4, names[4]);
        Param {
            reserved: self.int_field(entry, 0, names[0]),
            link_path_size: self.int_field(entry, 1, names[1]),
            link_path: self.path_field(entry, 2),
            descriptor: self.int_field(entry, 3, names[3]).map(Descriptor),
            data_type: data_type.map(DataType::from_code),
            data_size: self.int_field(entry, 5, names[5]),
            name: self.string_field(entry, 6, names[6]),
            units: self.string_field(entry, 7, names[7]),
            help: self.string_field(entry, 8, names[8]),
            min: self.value_field(entry, 9, names[9]),
            max: self.value_field(entry, 10, names[10]),
            default: self.value_field(entry, 11, names[11]),
            scaling: Scaling {
                multiplier: self.int_field(entry, 12, names[12]),
                divisor: self.int_field(entry, 13, names[13]),
                base: self.int_field(entry, 14, names[14]),
                offset: self.int_field(entry, 15, names[15]),
            },
            links: ScalingLinks {
                multiplier: self.int_field(entry, 16, names[16]),
                divisor: self.int_field(entry, 17, names[17]),
                base: self.int_field(entry, 18, names[18]),
                offset: self.int_field(entry, 19, names[19]),
            },
            decimal_places: self.int_field(entry, 20, names[20]),
            extra: entry.fields.iter().skip(Param::FIELD_COUNT).map(|f| f.value.clone()).collect(),
        }
    }

    fn enum_pairs(&mut self, entry: &RawEntry) -> Vec<EnumEntry> {
        if entry.fields.len() % 2 != 0 {
            self.error(
                Rule::FieldCount,
                entry.span,
                format!(
                    "`{}` has {} fields; enum strings come in value, \"text\" pairs",
                    entry.keyword,
                    entry.fields.len()
                ),
            );
        }
        let mut pairs: Vec<EnumEntry> = Vec::new();
        let mut seen: HashMap<i128, Span> = HashMap::new();
        for i in (0..entry.fields.len() / 2).map(|i| i * 2) {
            let Some(value) = self.int_field::<i128>(entry, i, "enum value") else {
                continue;
            };
            let span = entry.fields[i].span;
            if let Some(first) = seen.get(&value) {
                self.error(
                    Rule::DuplicateEntry,
                    span,
                    format!("`{}` names value {value} twice (first at {first})", entry.keyword),
                );
                continue;
            }
            seen.insert(value, span);
            let text = self.string_field(entry, i + 1, "enum string");
            pairs.push(EnumEntry { value, text });
        }
        pairs
    }

    fn enum_par(&mut self, entries: &[&RawEntry]) -> EnumParSection {
        let mut section = EnumParSection::default();
        for &entry in entries {
            match numbered_as(&entry.keyword, "param") {
                Some(n) => {
                    let strings =
                        (0..entry.fields.len()).map(|i| self.string_field(entry, i, "enum string")).collect();
                    section.enums.insert(n, strings);
                }
                None => {
                    self.unknown_keyword(entry, Known::EnumPar);
                    section.other.push(entry.clone());
                }
            }
        }
        section
    }

    fn groups(&mut self, entries: &[&RawEntry]) -> GroupsSection {
        let mut section = GroupsSection::default();
        for &entry in entries {
            let Some(n) = numbered_as(&entry.keyword, "group") else {
                self.unknown_keyword(entry, Known::Groups);
                section.other.push(entry.clone());
                continue;
            };
            self.need_fields(entry, 2, "a group (name, count, parameters...)");
            let name = self.string_field(entry, 0, "name");
            let count: Option<u32> = self.int_field(entry, 1, "parameter count");
            let mut params = Vec::new();
            let mut listed_once = std::collections::HashSet::new();
            for i in 2..entry.fields.len() {
                if entry.fields[i].value.is_empty() {
                    self.error(
                        Rule::InvalidValue,
                        entry.fields[i].span,
                        format!("`{}` lists an empty parameter number", entry.keyword),
                    );
                    continue;
                }
                if let Some(p) = self.int_field::<u32>(entry, i, "parameter number") {
                    if !listed_once.insert(p) {
                        self.warning(
                            Rule::GroupCount,
                            entry.fields[i].span,
                            format!("`{}` lists Param{p} twice", entry.keyword),
                        );
                    }
                    params.push(p);
                }
            }
            let listed = entry.fields.len().saturating_sub(2);
            if let Some(count) = count.filter(|&c| usize::try_from(c).ok() != Some(listed)) {
                self.warning(
                    Rule::GroupCount,
                    entry.fields.get(1).map_or(entry.span, |f| f.span),
                    format!("`{}` declares {count} parameters but lists {listed}", entry.keyword),
                );
            }
            section.groups.insert(n, Group { name, params });
        }
        section
    }
}

fn describe(value: &FieldValue) -> String {
    match value {
        FieldValue::Empty => "nothing".to_string(),
        FieldValue::Text(text) => format!("`{text}`"),
        FieldValue::Str(text) => format!("the string \"{text}\""),
        FieldValue::List(_) => "a { } group".to_string(),
    }
}
