use super::*;

fn node(mac: u8) -> ProjectNode {
    ProjectNode {
        mac,
        connection: "poll".into(),
        input_size: 18,
        output_size: 8,
        name: Some("feeder".into()),
        keying: Keying::Exact,
        identity: NodeIdentity {
            vendor_id: 0x1234,
            device_type: 0x0C,
            product_code: 1,
            major_revision: 1,
            minor_revision: 2,
            product_name: "Serial-DeviceNet Bridge".into(),
            serial_number: Some(0x1234_5678),
        },
        configuration: Some("[network]\nmac_id = 5\n\n[profile.serial]\nbaud = 9600\n".into()),
        param: vec![ProjectParam {
            number: 1,
            name: "Serial baud rate".into(),
            value: Some(9600),
            raw: None,
            units: "baud".into(),
            read_only: false,
        }],
    }
}

fn project(nodes: Vec<ProjectNode>) -> Project {
    Project { format: FORMAT, node: nodes }
}

/// A configuration the description reader accepts: the reference device's.
fn reference_config() -> String {
    slave_fw::description::DeviceDescription::reference().to_toml().unwrap()
}

#[test]
fn written_project_reads_back() {
    let mut n = node(5);
    n.configuration = Some(reference_config());
    let p = project(vec![n, ProjectNode { configuration: None, param: vec![], ..node(7) }]);
    let text = write(&p, "header line");
    assert!(text.starts_with("# header line\n"));
    assert_eq!(parse(&text, "p.toml"), Ok(p));
}

#[test]
fn equal_projects_have_no_difference_and_count_what_was_compared() {
    let p = project(vec![node(5)]);
    let c = compare(&p, &p);
    assert_eq!(c.differences, vec![]);
    assert_eq!((c.compared, c.params_compared), (1, 1));
    assert_eq!(c.configuration_keys_compared, 2);
}

#[test]
fn differences_name_node_key_and_parameter() {
    let file = project(vec![node(5), node(6)]);
    let mut changed = node(5);
    changed.param[0].value = Some(19200);
    changed.configuration = Some("[network]\nmac_id = 5\n\n[profile.serial]\nbaud = 19200\n".into());
    changed.identity.minor_revision = 3;
    let network = project(vec![changed, node(9)]);
    let c = compare(&file, &network);
    let text: Vec<String> = c.differences.iter().map(ToString::to_string).collect();
    assert_eq!(
        text,
        vec![
            "MAC 5: identity minor_revision (keying exact): file 2, network 3",
            "MAC 5: configuration profile.serial.baud: file 9600, network 19200",
            "MAC 5: parameter 1 (Serial baud rate): file 9600, network 19200",
            "MAC 6: node: file present, network absent (no answer)",
            "MAC 9: node: file absent, network present (Serial-DeviceNet Bridge)",
        ]
    );
    assert_eq!(c.compared, 1);
}

#[test]
fn keying_compatible_accepts_a_newer_minor_and_disabled_ignores_identity() {
    let mut f = node(5);
    f.keying = Keying::Compatible;
    let mut n = node(5);
    n.identity.minor_revision = 4;
    assert!(compare(&project(vec![f.clone()]), &project(vec![n.clone()])).differences.is_empty());
    n.identity.minor_revision = 1;
    assert_eq!(compare(&project(vec![f.clone()]), &project(vec![n.clone()])).differences.len(), 1);
    f.keying = Keying::Disabled;
    n.identity.vendor_id = 1;
    assert!(compare(&project(vec![f]), &project(vec![n])).differences.is_empty());
}

fn error_of(text: &str) -> ProjectError {
    parse(text, "p.toml").unwrap_err()
}

const HEAD: &str = "format = 1\n[[node]]\nmac = 5\ninput_size = 1\noutput_size = 1\n";
const ID: &str = "[node.identity]\nvendor_id = 1\ndevice_type = 2\nproduct_code = 3\nmajor_revision = 1\nminor_revision = 1\n";

#[test]
fn unknown_keys_name_file_and_line() {
    let e = error_of(&format!("{HEAD}colour = 1\n{ID}"));
    assert_eq!(e.line, 6, "{e}");
    assert!(e.to_string().starts_with("p.toml:6: "), "{e}");
    assert!(e.message.contains("colour"), "{e}");
    let e = error_of(&format!("{HEAD}{ID}vendor = 3\n"));
    assert_eq!(e.line, 12, "{e}");
    let e = error_of(&format!("{HEAD}{ID}[[node.param]]\nnumber = 1\nname = \"x\"\nvalu = 3\n"));
    assert_eq!(e.line, 15, "{e}");
    assert!(e.message.contains("valu"), "{e}");
}

#[test]
fn bad_values_name_the_line() {
    let e = error_of(&format!("{HEAD}keying = \"loose\"\n{ID}"));
    assert_eq!(e.line, 6, "{e}");
    let e = error_of(&(HEAD.replace("mac = 5", "mac = 64") + ID));
    assert_eq!(e.line, 3, "{e}");
    assert!(e.message.contains("0..=63"), "{e}");
    let e = error_of(&format!("{HEAD}{ID}{}{ID}", HEAD.replace("format = 1\n", "")));
    assert!(e.message.contains("given twice"), "{e}");
    let e = error_of(&format!("{HEAD}connection = \"fast\"\n{ID}"));
    assert_eq!(e.line, 6, "{e}");
    let e = error_of("format = 2\n");
    assert!(e.message.contains("format 2"), "{e}");
}

#[test]
fn a_configuration_error_names_the_project_line() {
    let mut config = reference_config();
    config.push_str("\n[colour]\nred = 1\n");
    let bad_line = config.lines().count() - 1;
    let text = format!("{HEAD}configuration = '''\n{config}'''\n{ID}");
    let e = error_of(&text);
    // HEAD is 5 lines, `configuration = '''` is line 6, the description's line k is line 6 + k.
    assert_eq!(e.line, 6 + bad_line, "{e}");
    assert!(e.message.contains("MAC 5 configuration"), "{e}");
}

#[test]
fn flattening_names_array_tables_by_index() {
    let flat = flatten_toml("[a]\nb = 1\n[[a.c]]\nd = 2\n[[a.c]]\nd = 3\n");
    let keys: Vec<&str> = flat.keys().map(String::as_str).collect();
    assert_eq!(keys, vec!["a.b", "a.c[0].d", "a.c[1].d"]);
}
