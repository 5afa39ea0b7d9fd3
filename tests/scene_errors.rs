//! Bad scenes: every failure class must give an error (never a panic) that
//! names the file, the line and the column, quotes the offending line with a
//! caret under the column and, where it helps, lists the valid choices.
//!
//! Columns: an attribute problem points at the attribute, an element problem
//! (including a property element such as `<float …>`) at its `<`.

use snell::{LoadOptions, SceneError};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// A valid sensor block: 8 lines, so a body passed to [`scene`] starts at line 9.
const HEAD: &str = r#"<scene version="3.0.0">
    <sensor type="perspective">
        <float name="fov" value="40"/>
        <film type="hdrfilm">
            <integer name="width" value="8"/>
            <integer name="height" value="6"/>
        </film>
    </sensor>
"#;

fn scene(body: &str) -> String {
    format!("{HEAD}{body}</scene>\n")
}

fn scene_path() -> PathBuf {
    std::env::temp_dir().join("snell-scene-errors").join("test.xml")
}

fn options(params: &[(&str, &str)]) -> LoadOptions {
    LoadOptions {
        params: params.iter().map(|(k, v)| (k.to_string(), v.to_string())).collect::<HashMap<_, _>>(),
        ..LoadOptions::default()
    }
}

/// A fresh folder for scenes that refer to files.
fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("snell-scene-errors-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[track_caller]
fn load_err_with(path: &Path, text: &str, params: &[(&str, &str)]) -> SceneError {
    match snell::load_str(path, text, &options(params)) {
        Ok(_) => panic!("expected loading to fail:\n{text}"),
        Err(e) => e,
    }
}

#[track_caller]
fn load_err(text: &str) -> SceneError {
    load_err_with(&scene_path(), text, &[])
}

/// Checks the error's location (file, line, column), that the text at the
/// column starts with `at`, that the message contains `message`, and that the
/// rendered error quotes the line and puts the caret under the column.
#[track_caller]
fn assert_error(e: &SceneError, file: &Path, line: u32, col: u32, at: &str, message: &str) {
    let shown = e.to_string();
    let loc = e.location.as_ref().unwrap_or_else(|| panic!("the error has no location:\n{shown}"));
    assert_eq!(loc.file.path, file, "wrong file:\n{shown}");
    assert_eq!((loc.line, loc.col), (line, col), "wrong line:column:\n{shown}");
    let source_line = loc.file.text.lines().nth(line as usize - 1).unwrap_or("");
    let from_col: String = source_line.chars().skip(col as usize - 1).collect();
    assert!(from_col.starts_with(at), "expected the column to point at {at:?}, it points at {from_col:?}:\n{shown}");
    assert!(e.message.contains(message), "expected the message to contain {message:?}:\n{shown}");

    assert!(shown.starts_with(&format!("error: {}", e.message)), "{shown}");
    assert!(shown.contains(&format!("--> {}:{line}:{col}\n", file.display())), "{shown}");
    assert!(shown.contains(&format!("\n{line} | {}\n", source_line.replace('\t', " "))), "the line is not quoted:\n{shown}");
    let caret = format!(" | {}^", " ".repeat(col as usize - 1));
    assert!(shown.lines().any(|l| l.trim_start().starts_with('|') && l.ends_with(&caret)), "no caret under column {col}:\n{shown}");
}

#[track_caller]
fn assert_help(e: &SceneError, words: &[&str]) {
    let help = e.help.as_deref().unwrap_or_else(|| panic!("the error has no help:\n{e}"));
    for w in words {
        assert!(help.contains(w), "expected the help to mention {w:?}:\n{e}");
    }
    assert!(e.to_string().contains(&format!("= help: {help}")), "{e}");
}

// ------------------------------------------------------------- malformed XML

#[test]
fn malformed_xml_unclosed_tag() {
    let text = scene("    <shape type=\"sphere\">\n        <float name=\"radius\" value=\"1\"/>\n");
    let e = load_err(&text);
    // Found when </scene> closes the still-open <shape>.
    assert_error(&e, &scene_path(), 11, 1, "</scene>", "malformed XML");
    assert!(e.message.contains("'shape'"), "{e}");
}

#[test]
fn malformed_xml_unquoted_attribute() {
    let e = load_err(&scene("    <bsdf type=diffuse/>\n"));
    assert_error(&e, &scene_path(), 9, 16, "diffuse", "malformed XML");
}

#[test]
fn malformed_xml_truncated_file() {
    let text = scene("    <shape type=\"sphere\"/>\n");
    let cut = &text[..text.find("<shape").unwrap() + 3];
    let e = load_err(cut);
    // roxmltree reports the root element that is never closed.
    assert_error(&e, &scene_path(), 1, 1, "<scene", "malformed XML");
    assert!(e.message.contains("never closed"), "{e}");
}

#[test]
fn wrong_root_element_and_missing_version() {
    let e = load_err("<scen version=\"3.0.0\">\n</scen>\n");
    assert_error(&e, &scene_path(), 1, 1, "<scen", "expected <scene>");
    let e = load_err("<scene>\n</scene>\n");
    assert_error(&e, &scene_path(), 1, 1, "<scene>", "no version");
    assert_help(&e, &["version=\"3.0.0\""]);
    // Versions before 2.0.0 are upgraded (tests/documents.rs); one that is
    // not a version number is refused.
    let e = load_err("<scene version=\"0.x.5\">\n</scene>\n");
    assert_error(&e, &scene_path(), 1, 8, "version=", "unsupported scene version");
    assert_help(&e, &["3.0.0"]);
}

// ------------------------------------------------------------ unknown things

#[test]
fn unknown_bsdf_plugin() {
    let e = load_err(&scene("    <bsdf type=\"difuse\"/>\n"));
    assert_error(&e, &scene_path(), 9, 5, "<bsdf type=\"difuse\"", "unknown bsdf plugin \"difuse\"");
    assert_help(&e, &["blendbsdf, bumpmap, conductor, dielectric, diffuse, mask, normalmap, null, plastic, polarizer, pplastic, principled, principledthin, retarder, roughconductor, roughdielectric, roughplastic, thindielectric, twosided"]);
}

// ------------------------------------------------- specular material inputs

#[test]
fn unknown_named_ior() {
    let e = load_err(&scene("    <bsdf type=\"dielectric\">\n        <string name=\"int_ior\" value=\"crystal\"/>\n    </bsdf>\n"));
    assert_error(&e, &scene_path(), 10, 9, "<string name=\"int_ior\"", "unknown index of refraction \"crystal\"");
    assert_help(&e, &["bk7", "water", "diamond", "crown glass", "fused quartz"]);
}

#[test]
fn ior_of_the_wrong_type_or_not_positive() {
    let e = load_err(&scene("    <bsdf type=\"plastic\">\n        <rgb name=\"ext_ior\" value=\"1, 1, 1\"/>\n    </bsdf>\n"));
    assert_error(&e, &scene_path(), 10, 9, "<rgb name=\"ext_ior\"", "expected float or string");
    let e = load_err(&scene("    <bsdf type=\"thindielectric\">\n        <float name=\"int_ior\" value=\"-1.5\"/>\n    </bsdf>\n"));
    assert_error(&e, &scene_path(), 10, 9, "<float name=\"int_ior\"", "must be a positive number");
}

#[test]
fn malformed_spectrum_lists() {
    for value in ["400:0.5, 380:0.2", "400:0.5", "400:0.5, 500", "400:0.5, 500:x"] {
        let e = load_err(&scene(&format!("    <bsdf type=\"diffuse\">\n        <spectrum name=\"reflectance\" value=\"{value}\"/>\n    </bsdf>\n")));
        assert_error(&e, &scene_path(), 10, 38, "value=", "is neither a constant nor a list of wavelength:value pairs");
        assert_help(&e, &["400:0.1, 500:0.4", "increasing"]);
    }
}

#[test]
fn bad_dispersive_ior() {
    let e = load_err(&scene("    <bsdf type=\"dielectric\">\n        <string name=\"int_ior\" value=\"sellmeier:flint\"/>\n    </bsdf>\n"));
    assert_error(&e, &scene_path(), 10, 9, "<string name=\"int_ior\"", "unknown dispersive medium \"flint\"");
    assert!(format!("{e}").contains("bk7, fused silica, sf11, water, diamond"), "{e}");
    let e = load_err(&scene("    <bsdf type=\"dielectric\">\n        <string name=\"ext_ior\" value=\"cauchy(1.5)\"/>\n    </bsdf>\n"));
    assert_error(&e, &scene_path(), 10, 9, "<string name=\"ext_ior\"", "cauchy(A, B) needs 2 coefficients");
    // A thin pane does not bend light, so it cannot disperse it.
    let e = load_err(&scene("    <bsdf type=\"thindielectric\">\n        <string name=\"int_ior\" value=\"sellmeier:bk7\"/>\n    </bsdf>\n"));
    assert_error(&e, &scene_path(), 10, 9, "<string name=\"int_ior\"", "cannot disperse");
    // Plastic takes constants only: a dispersive form is an unknown name there.
    let e = load_err(&scene("    <bsdf type=\"plastic\">\n        <string name=\"int_ior\" value=\"sellmeier:bk7\"/>\n    </bsdf>\n"));
    assert_error(&e, &scene_path(), 10, 9, "<string name=\"int_ior\"", "unknown index of refraction");
}

#[test]
fn unknown_metal_and_conflicting_conductor_inputs() {
    let e = load_err(&scene("    <bsdf type=\"conductor\">\n        <string name=\"material\" value=\"Gold\"/>\n    </bsdf>\n"));
    assert_error(&e, &scene_path(), 10, 9, "<string name=\"material\"", "unknown conductor material \"Gold\"");
    assert_help(&e, &["Au", "Ag", "Cu", "none"]);
    let e = load_err(&scene(
        "    <bsdf type=\"conductor\">\n        <string name=\"material\" value=\"Au\"/>\n        <float name=\"eta\" value=\"0.2\"/>\n    </bsdf>\n",
    ));
    assert_error(&e, &scene_path(), 10, 9, "<string name=\"material\"", "not both");
}

/// Mitsuba 3.9.1 plugins that Snell lacks say so (not "unknown", which
/// suggests a typo), still listing what Snell has.
#[test]
fn mitsuba3_plugins_snell_lacks_are_named_as_such() {
    let cases: &[(&str, &str, &[&str])] = &[
        ("    <emitter type=\"sunsky\"/>\n", "Mitsuba 3's emitter plugin \"sunsky\" (Hosek–Wilkie sky and sun) is not supported yet", &["envmap", "constant"]),
        ("    <bsdf type=\"hair\"/>\n", "Mitsuba 3's bsdf plugin \"hair\"", &["diffuse", "principled"]),
        ("    <integrator type=\"prb_projective\"/>\n", "path renders the same image", &["path", "volpath", "prb"]),
        ("    <shape type=\"ellipsoids\"/>\n", "not supported yet", &["sphere", "ply"]),
    ];
    for (body, message, choices) in cases {
        let e = load_err(&scene(body));
        assert_error(&e, &scene_path(), 9, 5, "<", message);
        assert_help(&e, choices);
    }
    let text = HEAD.replace("type=\"perspective\"", "type=\"batch\"") + "</scene>\n";
    let e = load_err(&text);
    assert_error(&e, &scene_path(), 2, 5, "<sensor", "sensor plugin \"batch\" (a multi-view sensor) is not supported yet");
}

#[test]
fn twosided_rejects_transmitting_bsdfs() {
    let e = load_err(&scene("    <bsdf type=\"twosided\">\n        <bsdf type=\"dielectric\"/>\n    </bsdf>\n"));
    assert_error(&e, &scene_path(), 10, 9, "<bsdf type=\"dielectric\"", "cannot nest a transmitting BSDF");
}

#[test]
fn unknown_plugin_of_every_kind() {
    let cases: &[(&str, &[&str])] = &[
        ("    <shape type=\"sphre\"/>\n", &["rectangle", "cube", "disk", "sphere", "obj", "ply"]),
        ("    <emitter type=\"skylight\"/>\n", &["area", "point", "spot", "constant", "directional", "envmap", "projector"]),
        ("    <integrator type=\"volumetric\"/>\n", &["direct", "path", "ptracer", "bdpt", "sppm", "volpath"]),
        ("    <texture type=\"noise\"/>\n", &["bitmap", "checkerboard"]),
    ];
    for (body, choices) in cases {
        let e = load_err(&scene(body));
        assert_error(&e, &scene_path(), 9, 5, "<", "plugin");
        assert_help(&e, choices);
    }
    // Inside the sensor.
    let text = HEAD.replace("type=\"hdrfilm\"", "type=\"ldrfilm\"") + "</scene>\n";
    let e = load_err(&text);
    assert_error(&e, &scene_path(), 4, 9, "<film", "unknown film plugin \"ldrfilm\"");
    assert_help(&e, &["hdrfilm"]);
    let text = HEAD.replace("type=\"perspective\"", "type=\"pinhole\"") + "</scene>\n";
    let e = load_err(&text);
    assert_error(&e, &scene_path(), 2, 5, "<sensor", "unknown sensor plugin \"pinhole\"");
    assert_help(&e, &["perspective", "orthographic", "thinlens"]);
    let text = HEAD.replace("        </film>", "            <rfilter type=\"blackman\"/>\n        </film>") + "</scene>\n";
    let e = load_err(&text);
    assert_error(&e, &scene_path(), 7, 13, "<rfilter", "unknown rfilter plugin \"blackman\"");
    assert_help(&e, &["box", "tent", "gaussian", "mitchell", "catmullrom", "lanczos"]);
}

#[test]
fn unknown_element_tag() {
    let e = load_err(&scene("    <shape type=\"sphere\">\n        <radius value=\"1\"/>\n    </shape>\n"));
    assert_error(&e, &scene_path(), 10, 9, "<radius", "unknown element <radius>");
    assert_help(&e, &["shape", "bsdf", "float", "ref", "include"]);
}

#[test]
fn unknown_attribute() {
    let e = load_err(&scene("    <shape type=\"sphere\" color=\"red\"/>\n"));
    assert_error(&e, &scene_path(), 9, 26, "color=", "unexpected attribute \"color\" on <shape>");
    assert_help(&e, &["type", "id", "name"]);
}

#[test]
fn missing_type_attribute() {
    let e = load_err(&scene("    <shape/>\n"));
    assert_error(&e, &scene_path(), 9, 5, "<shape", "needs a \"type\" attribute");
}

#[test]
fn unknown_transform_operation() {
    let e = load_err(&scene(
        "    <shape type=\"sphere\">\n        <transform name=\"to_world\">\n            <shear value=\"1\"/>\n        </transform>\n    </shape>\n",
    ));
    assert_error(&e, &scene_path(), 11, 13, "<shear", "unknown transform operation <shear>");
    assert_help(&e, &["translate", "rotate", "scale", "matrix", "lookat"]);
}

// -------------------------------------------------------- missing parameters

#[test]
fn area_emitter_without_radiance() {
    let e = load_err(&scene("    <shape type=\"sphere\">\n        <emitter type=\"area\"/>\n    </shape>\n"));
    assert_error(&e, &scene_path(), 10, 9, "<emitter", "area emitter needs \"radiance\"");
}

#[test]
fn perspective_sensor_with_fov_and_focal_length() {
    // Without "fov" a perspective sensor uses Mitsuba's focal_length (50mm,
    // tests/sensors.rs); both at once is an error at the focal length.
    let text = HEAD.replace(
        "        <float name=\"fov\" value=\"40\"/>\n",
        "        <float name=\"fov\" value=\"40\"/>\n        <string name=\"focal_length\" value=\"35mm\"/>\n",
    ) + "</scene>\n";
    let e = load_err(&text);
    assert_error(&e, &scene_path(), 4, 9, "<string name=\"focal_length\"", "either a field of view (\"fov\") or a focal length");
    let text = HEAD.replace("        <float name=\"fov\" value=\"40\"/>\n", "        <string name=\"focal_length\" value=\"long\"/>\n") + "</scene>\n";
    let e = load_err(&text);
    assert_error(&e, &scene_path(), 3, 9, "<string name=\"focal_length\"", "focal length \"long\" is not of the form <x>mm");
    // A thin lens needs its aperture.
    let text = HEAD.replace("type=\"perspective\"", "type=\"thinlens\"") + "</scene>\n";
    let e = load_err(&text);
    assert_error(&e, &scene_path(), 2, 5, "<sensor", "needs the float property \"aperture_radius\"");
}

#[test]
fn mesh_without_filename() {
    let e = load_err(&scene("    <shape type=\"obj\"/>\n"));
    assert_error(&e, &scene_path(), 9, 5, "<shape", "shape \"obj\" needs the string property \"filename\"");
}

#[test]
fn point_emitter_without_intensity() {
    let e = load_err(&scene("    <emitter type=\"point\">\n        <point name=\"position\" value=\"0, 1, 0\"/>\n    </emitter>\n"));
    assert_error(&e, &scene_path(), 9, 5, "<emitter", "point emitter needs \"intensity\"");
}

#[test]
fn property_without_value() {
    let e = load_err(&scene("    <shape type=\"sphere\">\n        <float name=\"radius\"/>\n    </shape>\n"));
    assert_error(&e, &scene_path(), 10, 9, "<float", "needs a \"value\" attribute");
}

// ---------------------------------------------------------- unused parameter

#[test]
fn unused_parameter() {
    let e = load_err(&scene("    <shape type=\"sphere\">\n        <float name=\"radius2\" value=\"1\"/>\n    </shape>\n"));
    assert_error(&e, &scene_path(), 10, 9, "<float name=\"radius2\"", "unused parameter \"radius2\"");
    assert!(e.message.contains("shape \"sphere\""), "{e}");

    let e = load_err(&scene("    <bsdf type=\"diffuse\">\n        <rgb name=\"reflectence\" value=\"0.5\"/>\n    </bsdf>\n"));
    assert_error(&e, &scene_path(), 10, 9, "<rgb", "unused parameter \"reflectence\"");
}

#[test]
fn unexpected_nested_object() {
    let e = load_err(&scene("    <shape type=\"sphere\">\n        <texture type=\"checkerboard\"/>\n    </shape>\n"));
    assert_error(&e, &scene_path(), 10, 9, "<texture", "unexpected nested <texture>");
}

#[test]
fn property_given_twice() {
    let e = load_err(&scene(
        "    <shape type=\"sphere\">\n        <float name=\"radius\" value=\"1\"/>\n        <float name=\"radius\" value=\"2\"/>\n    </shape>\n",
    ));
    assert_error(&e, &scene_path(), 11, 9, "<float", "\"radius\" is given twice (first at line 10)");
}

// ---------------------------------------------------------- wrong value type

#[test]
fn string_where_a_float_is_expected() {
    let text = HEAD.replace("<float name=\"fov\" value=\"40\"/>", "<string name=\"fov\" value=\"x\"/>") + "</scene>\n";
    let e = load_err(&text);
    assert_error(&e, &scene_path(), 3, 9, "<string", "property \"fov\" of sensor \"perspective\" has type string, expected float");
}

#[test]
fn float_that_is_not_a_number() {
    let text = HEAD.replace("<float name=\"fov\" value=\"40\"/>", "<float name=\"fov\" value=\"abc\"/>") + "</scene>\n";
    let e = load_err(&text);
    assert_error(&e, &scene_path(), 3, 27, "value=\"abc\"", "\"abc\" is not a number");
}

#[test]
fn integer_that_is_not_an_integer() {
    let text = HEAD.replace("<integer name=\"width\" value=\"8\"/>", "<integer name=\"width\" value=\"1.5\"/>") + "</scene>\n";
    let e = load_err(&text);
    assert_error(&e, &scene_path(), 5, 35, "value=\"1.5\"", "\"1.5\" is not an integer");
}

#[test]
fn float_where_an_integer_is_expected() {
    let text = HEAD.replace("<integer name=\"width\" value=\"8\"/>", "<float name=\"width\" value=\"8\"/>") + "</scene>\n";
    let e = load_err(&text);
    assert_error(&e, &scene_path(), 5, 13, "<float", "has type float, expected integer");
}

#[test]
fn malformed_boolean_rgb_and_vector() {
    let e = load_err(&scene("    <shape type=\"sphere\">\n        <boolean name=\"flip_normals\" value=\"yes\"/>\n    </shape>\n"));
    assert_error(&e, &scene_path(), 10, 38, "value=", "\"yes\" is not a boolean");
    assert_help(&e, &["true", "false"]);

    let e = load_err(&scene("    <bsdf type=\"diffuse\">\n        <rgb name=\"reflectance\" value=\"0.5, 0.5\"/>\n    </bsdf>\n"));
    assert_error(&e, &scene_path(), 10, 33, "value=", "is not an RGB value");

    let e = load_err(&scene("    <shape type=\"sphere\">\n        <point name=\"center\" x=\"1\" y=\"oops\"/>\n    </shape>\n"));
    assert_error(&e, &scene_path(), 10, 36, "y=\"oops\"", "\"oops\" is not a number");
}

#[test]
fn invalid_choice_lists_the_choices() {
    let text = HEAD.replace("<float name=\"fov\" value=\"40\"/>", "<float name=\"fov\" value=\"40\"/><string name=\"fov_axis\" value=\"z\"/>")
        + "</scene>\n";
    let e = load_err(&text);
    assert_error(&e, &scene_path(), 3, 39, "<string", "\"z\" is not a valid value of \"fov_axis\"");
    assert_help(&e, &["x", "y", "smaller", "larger", "diagonal"]);
}

// ------------------------------------------------------- out-of-range values

#[test]
fn negative_radius() {
    let e = load_err(&scene("    <shape type=\"sphere\">\n        <float name=\"radius\" value=\"-1\"/>\n    </shape>\n"));
    assert_error(&e, &scene_path(), 10, 9, "<float name=\"radius\"", "\"radius\" must be positive");
}

#[test]
fn zero_width() {
    let text = HEAD.replace("<integer name=\"width\" value=\"8\"/>", "<integer name=\"width\" value=\"0\"/>") + "</scene>\n";
    let e = load_err(&text);
    assert_error(&e, &scene_path(), 5, 13, "<integer name=\"width\"", "\"width\" must be between 1 and 65536");
}

#[test]
fn fov_out_of_range_and_zero_samples() {
    let text = HEAD.replace("value=\"40\"", "value=\"180\"") + "</scene>\n";
    let e = load_err(&text);
    assert_error(&e, &scene_path(), 3, 9, "<float name=\"fov\"", "\"fov\" must be an angle in (0, 180) degrees");

    let text = HEAD.replace(
        "        </film>\n",
        "        </film>\n        <sampler type=\"independent\">\n            <integer name=\"sample_count\" value=\"0\"/>\n        </sampler>\n",
    ) + "</scene>\n";
    let e = load_err(&text);
    assert_error(&e, &scene_path(), 9, 13, "<integer", "\"sample_count\" must be between 1 and 16777216");
}

#[test]
fn non_finite_and_degenerate_values() {
    let e = load_err(&scene("    <shape type=\"sphere\">\n        <float name=\"radius\" value=\"inf\"/>\n    </shape>\n"));
    assert_error(&e, &scene_path(), 10, 9, "<float", "is not finite");
    let e = load_err(&scene(
        "    <shape type=\"sphere\">\n        <transform name=\"to_world\">\n            <scale value=\"0\"/>\n        </transform>\n    </shape>\n",
    ));
    assert_error(&e, &scene_path(), 11, 13, "<scale", "degenerate");
}

// ----------------------------------------------------------------- $params

#[test]
fn undefined_parameter() {
    let body = "    <shape type=\"sphere\">\n        <float name=\"radius\" value=\"$r\"/>\n    </shape>\n";
    let e = load_err(&scene(body));
    assert_error(&e, &scene_path(), 10, 30, "value=\"$r\"", "undefined parameter \"$r\"");
    assert_help(&e, &["<default", "-D"]);

    // The same scene loads once the parameter is given on the command line.
    snell::load_str(&scene_path(), &scene(body), &options(&[("r", "0.5")])).unwrap_or_else(|e| panic!("{e}"));
    // ... or with a <default>.
    let with_default = scene(&format!("    <default name=\"r\" value=\"2\"/>\n{body}"));
    snell::load_str(&scene_path(), &with_default, &options(&[])).unwrap_or_else(|e| panic!("{e}"));
    // -D wins over the default, and its value is checked where it is used.
    let e = load_err_with(&scene_path(), &with_default, &[("r", "-3")]);
    assert_error(&e, &scene_path(), 11, 9, "<float", "\"radius\" must be positive");
}

#[test]
fn undefined_parameter_lists_the_defined_ones() {
    let body = "    <default name=\"radius\" value=\"1\"/>\n    <shape type=\"sphere\">\n        <float name=\"radius\" value=\"$radiu\"/>\n    </shape>\n";
    let e = load_err(&scene(body));
    assert_error(&e, &scene_path(), 11, 30, "value=", "undefined parameter \"$radiu\"");
    assert_help(&e, &["radius"]);
}

// ------------------------------------------------------------------- ids

#[test]
fn reference_to_unknown_id() {
    let body = "    <bsdf type=\"diffuse\" id=\"white\"/>\n    <shape type=\"sphere\">\n        <ref id=\"whte\"/>\n    </shape>\n";
    let e = load_err(&scene(body));
    assert_error(&e, &scene_path(), 11, 9, "<ref", "reference to unknown id \"whte\"");
    assert_help(&e, &["white"]);
}

#[test]
fn named_reference_to_unknown_id() {
    let body = "    <bsdf type=\"diffuse\">\n        <ref name=\"reflectance\" id=\"tex\"/>\n    </bsdf>\n";
    let e = load_err(&scene(body));
    assert_error(&e, &scene_path(), 10, 9, "<ref", "reference to unknown id \"tex\"");
    assert_help(&e, &["no object in this scene has an id"]);
}

#[test]
fn duplicate_id() {
    let body = "    <bsdf type=\"diffuse\" id=\"a\"/>\n    <shape type=\"sphere\">\n        <bsdf type=\"diffuse\" id=\"a\"/>\n    </shape>\n";
    let e = load_err(&scene(body));
    assert_error(&e, &scene_path(), 11, 9, "<bsdf", "id \"a\" is used twice (first at line 9)");
}

#[test]
fn reference_to_the_wrong_kind() {
    let body = "    <texture type=\"checkerboard\" id=\"t\"/>\n    <shape type=\"sphere\">\n        <ref id=\"t\"/>\n    </shape>\n";
    let e = load_err(&scene(body));
    assert_error(&e, &scene_path(), 11, 9, "<ref", "a shape cannot take a reference to a <texture>");
}

// -------------------------------------------------------------- files

#[test]
fn missing_mesh_files() {
    let dir = temp_dir("missing-mesh");
    let path = dir.join("scene.xml");
    for (plugin, file, what) in [("obj", "nothere.obj", "OBJ"), ("ply", "meshes/nothere.ply", "PLY")] {
        let body = format!("    <shape type=\"{plugin}\">\n        <string name=\"filename\" value=\"{file}\"/>\n    </shape>\n");
        let e = load_err_with(&path, &scene(&body), &[]);
        assert_error(&e, &path, 10, 9, "<string name=\"filename\"", &format!("{what} file"));
        // Relative names resolve against the scene's folder.
        assert!(e.message.contains(&dir.join(file).display().to_string()), "{e}");
    }
}

#[test]
fn bad_mesh_files() {
    let dir = temp_dir("bad-mesh");
    let path = dir.join("scene.xml");
    std::fs::write(dir.join("garbage.ply"), b"\x00\x01\x02garbage\xff\xfe not a ply file\n").unwrap();
    std::fs::write(
        dir.join("truncated.ply"),
        "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\x00\x00",
    )
    .unwrap();
    std::fs::write(
        dir.join("badindex.ply"),
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n",
    )
    .unwrap();
    std::fs::write(dir.join("badindex.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 5\n").unwrap();
    std::fs::write(dir.join("badnegative.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -9\n").unwrap();
    std::fs::write(dir.join("nofaces.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\n").unwrap();
    std::fs::write(dir.join("binary.obj"), b"\x00\xff\xfe\x01garbage\nf 1 2 3\n").unwrap();
    std::fs::write(dir.join("zeroindex.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n").unwrap();
    std::fs::write(dir.join("shortvertex.obj"), "v 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    std::fs::write(dir.join("nan.obj"), "v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    std::fs::write(dir.join("flat.obj"), "v 0 0 0\nv 0 0 0\nv 0 0 0\nf 1 2 3\n").unwrap();
    let header = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n";
    std::fs::write(dir.join("negative.ply"), format!("{header}3 0 1 -2\n")).unwrap();
    std::fs::write(dir.join("shortface.ply"), format!("{header}3 0 1\n")).unwrap();
    std::fs::write(dir.join("floatindex.ply"), header.replace("uchar int", "uchar float") + "3 0 1 2\n").unwrap();
    std::fs::write(dir.join("noz.ply"), header.replace("property float z\n", "")).unwrap();
    std::fs::write(
        dir.join("huge.ply"),
        b"ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\x00\x00",
    )
    .unwrap();
    for (plugin, file, message) in [
        ("ply", "garbage.ply", "cannot read PLY file"),
        ("ply", "truncated.ply", "cannot read PLY file"),
        ("ply", "badindex.ply", "vertex 7"),
        ("obj", "badindex.obj", "cannot read OBJ file"),
        ("obj", "badnegative.obj", "cannot read OBJ file"),
        ("obj", "nofaces.obj", "no faces"),
        ("obj", "binary.obj", "OBJ"),
        ("obj", "zeroindex.obj", "face vertex index out of bounds"),
        ("obj", "shortvertex.obj", "cannot read OBJ file"),
        ("obj", "nan.obj", "not a finite number"),
        ("ply", "negative.ply", "negative"),
        ("ply", "shortface.ply", "cannot read PLY file"),
        ("ply", "floatindex.ply", "no integer list"),
        ("ply", "noz.ply", "cannot read PLY file"),
        ("ply", "huge.ply", "cannot read PLY file"),
    ] {
        let body = format!("    <shape type=\"{plugin}\">\n        <string name=\"filename\" value=\"{file}\"/>\n    </shape>\n");
        let e = load_err_with(&path, &scene(&body), &[]);
        assert_error(&e, &path, 10, 9, "<string name=\"filename\"", message);
        assert!(e.message.contains(file), "the message should name {file}:\n{e}");
    }
    // A mesh that reads but has no area: reported at the shape.
    let body = "    <shape type=\"obj\">\n        <string name=\"filename\" value=\"flat.obj\"/>\n    </shape>\n";
    let e = load_err_with(&path, &scene(body), &[]);
    assert_error(&e, &path, 9, 5, "<shape", "this obj has zero or non-finite surface area");
}

#[test]
fn missing_and_bad_bitmap_files() {
    let dir = temp_dir("bitmap");
    let path = dir.join("scene.xml");
    std::fs::write(dir.join("garbage.png"), b"this is not an image").unwrap();
    for (file, message) in [("textures/nothere.png", "cannot open image"), ("garbage.png", "image")] {
        let body = format!(
            "    <bsdf type=\"diffuse\">\n        <texture type=\"bitmap\" name=\"reflectance\">\n            <string name=\"filename\" value=\"{file}\"/>\n        </texture>\n    </bsdf>\n"
        );
        let e = load_err_with(&path, &scene(&body), &[]);
        assert_error(&e, &path, 11, 13, "<string name=\"filename\"", message);
        assert!(e.message.contains(file), "the message should name {file}:\n{e}");
    }
}

/// Mitsuba 3.9.1's bitmap `format` (storage precision): a value it does not
/// know is located and the four it knows are listed.
#[test]
fn bitmap_format_choices() {
    let body = "    <bsdf type=\"diffuse\">\n        <texture type=\"bitmap\" name=\"reflectance\">\n            <string name=\"filename\" value=\"t.png\"/>\n            <string name=\"format\" value=\"fixed\"/>\n        </texture>\n    </bsdf>\n";
    let e = load_err(&scene(body));
    assert_error(&e, &scene_path(), 12, 13, "<string name=\"format\"", "format");
    assert_help(&e, &["auto", "variant", "float16", "uint8"]);
}

#[test]
fn include_of_a_missing_file() {
    let dir = temp_dir("include-missing");
    let path = dir.join("scene.xml");
    let e = load_err_with(&path, &scene("    <include filename=\"parts/missing.xml\"/>\n"), &[]);
    assert_error(&e, &path, 9, 14, "filename=", "cannot read included file");
    assert!(e.message.contains("missing.xml"), "{e}");
}

#[test]
fn error_inside_an_included_file_points_into_that_file() {
    let dir = temp_dir("include-bad");
    let path = dir.join("scene.xml");
    let part = dir.join("part.xml");
    std::fs::write(&part, "<scene version=\"3.0.0\">\n    <bsdf type=\"fur\"/>\n</scene>\n").unwrap();
    let text = scene("    <include filename=\"part.xml\"/>\n");
    std::fs::write(&path, &text).unwrap();
    let e = snell::load_file(&path, &LoadOptions::default()).err().expect("should fail");
    assert_error(&e, &part, 2, 5, "<bsdf", "unknown bsdf plugin \"fur\"");
    assert_help(&e, &["diffuse, mask, normalmap, null, plastic, polarizer, pplastic, principled, principledthin, retarder, roughconductor, roughdielectric, roughplastic, thindielectric, twosided"]);

    // Malformed XML in the included file, too.
    std::fs::write(&part, "<scene version=\"3.0.0\">\n    <bsdf type=\"diffuse\">\n</scene>\n").unwrap();
    let e = snell::load_file(&path, &LoadOptions::default()).err().expect("should fail");
    assert_error(&e, &part, 3, 1, "</scene>", "malformed XML");
}

#[test]
fn missing_scene_file() {
    let path = temp_dir("missing-scene").join("nothere.xml");
    let e = snell::load_file(&path, &LoadOptions::default()).err().expect("should fail");
    assert!(e.location.is_none());
    assert_eq!(e.path.as_deref(), Some(path.as_path()));
    let shown = e.to_string();
    assert!(shown.contains("cannot read scene file"), "{shown}");
    assert!(shown.contains(&path.display().to_string()), "{shown}");
}

// ----------------------------------------------------------- scene structure

#[test]
fn scene_without_sensor() {
    let e = load_err("<scene version=\"3.0.0\">\n    <shape type=\"sphere\"/>\n</scene>\n");
    assert_error(&e, &scene_path(), 1, 1, "<scene", "the scene has no <sensor>");
    assert_help(&e, &["<sensor type=\"perspective\">"]);
    // After an XML declaration, the root element is on its own line.
    let e = load_err("<?xml version=\"1.0\"?>\n<scene version=\"3.0.0\"/>\n");
    assert_error(&e, &scene_path(), 2, 1, "<scene", "the scene has no <sensor>");
}

#[test]
fn two_sensors() {
    let text = format!("{HEAD}{}</scene>\n", &HEAD[HEAD.find('\n').unwrap() + 1..]);
    let e = load_err(&text);
    assert_error(&e, &scene_path(), 9, 5, "<sensor", "more than one <sensor>");
}

#[test]
fn area_emitter_at_top_level() {
    let e = load_err(&scene("    <emitter type=\"area\">\n        <rgb name=\"radiance\" value=\"1\"/>\n    </emitter>\n"));
    assert_error(&e, &scene_path(), 9, 5, "<emitter", "must be nested inside the <shape>");
}

#[test]
fn columns_count_characters_and_tabs() {
    // "λ" is two bytes but one column; a tab is one column.
    let e = load_err(&scene("\t<!-- λ --><bsdf type=\"difuse\"/>\n"));
    assert_error(&e, &scene_path(), 9, 12, "<bsdf", "unknown bsdf plugin");
}

#[test]
fn valid_scene_loads() {
    let body = "    <shape type=\"sphere\">\n        <bsdf type=\"diffuse\"/>\n    </shape>\n    <emitter type=\"constant\"/>\n";
    let s = snell::load_str(&scene_path(), &scene(body), &LoadOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!((s.film.width, s.film.height), (8, 6));
}

// ---------------------------------------------------------------- fuzzing

/// A small deterministic generator (SplitMix64).
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

/// Loads `bytes` (as text, if it is UTF-8) and checks that an error, if any,
/// renders and points inside the text; a scene that loads is rendered at
/// 8×8 and 1 spp (RGB, or spectral for every other one) and must give
/// finite pixels. A panic fails the test.
fn load_never_panics(path: &Path, bytes: &[u8], params: &HashMap<String, String>, seen: &mut (usize, usize)) {
    let Ok(text) = std::str::from_utf8(bytes) else { return };
    let options = LoadOptions { params: params.clone(), spp: None, seed: None };
    let spectral = (seen.0 + seen.1) % 2 == 1;
    let result = std::panic::catch_unwind(|| {
        snell::load_str(path, text, &options).map(|mut scene| {
            scene.film.width = 8;
            scene.film.height = 8;
            scene.sampler.sample_count = 1;
            let options = snell::RenderOptions { threads: 1, ..snell::RenderOptions::default() };
            let image = if spectral {
                snell::render::<snell::spectrum::Sampled>(&scene, &options)
            } else {
                snell::render::<snell::spectrum::Rgb>(&scene, &options)
            };
            if let Ok((image, _)) = image {
                assert_eq!(image.pixels.len(), 64);
                assert!(image.pixels.iter().all(|p| p.is_finite()), "non-finite pixel rendering:\n{text}");
            }
        })
    });
    match result {
        Err(_) => panic!("load_str or the render panicked on this input:\n{text}"),
        Ok(Ok(())) => seen.0 += 1,
        Ok(Err(e)) => {
            seen.1 += 1;
            let shown = e.to_string();
            assert!(shown.starts_with("error: "), "{shown}");
            if let Some(loc) = &e.location {
                let lines = loc.file.text.lines().count() as u32;
                assert!(loc.line >= 1 && loc.line <= lines + 1, "line {} of {lines}:\n{shown}", loc.line);
                assert!(loc.col >= 1, "{shown}");
            }
        }
    }
}

#[test]
fn corrupted_scenes_never_panic() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box.xml");
    let original = std::fs::read(&path).unwrap();
    // Small film so that nothing big is allocated when a corruption still loads.
    let params: HashMap<String, String> = [("res", "8"), ("spp", "1")].iter().map(|(k, v)| (k.to_string(), v.to_string())).collect();
    let mut seen = (0, 0);
    load_never_panics(&path, &original, &params, &mut seen);
    assert_eq!(seen, (1, 0), "the original scene must load");

    // Every truncation.
    for n in 0..original.len() {
        load_never_panics(&path, &original[..n], &params, &mut seen);
    }
    // Single and multiple byte deletions.
    let mut rng = Rng(0x5eed);
    for i in 0..original.len() {
        let mut b = original.clone();
        b.remove(i);
        load_never_panics(&path, &b, &params, &mut seen);
    }
    for _ in 0..2000 {
        let mut b = original.clone();
        for _ in 0..1 + rng.below(8) {
            let i = rng.below(b.len());
            b.remove(i);
        }
        load_never_panics(&path, &b, &params, &mut seen);
    }
    // Byte substitutions with characters that matter to XML and numbers.
    let specials = b"<>/\"'=&$-.0 9eE\n\tx";
    for _ in 0..3000 {
        let mut b = original.clone();
        let i = rng.below(b.len());
        b[i] = specials[rng.below(specials.len())];
        load_never_panics(&path, &b, &params, &mut seen);
    }

    // Every attribute value replaced by each of a list of troublemakers.
    let text = std::str::from_utf8(&original).unwrap();
    let values = [
        "", " ", "0", "-1", "-0", "1e40", "-1e40", "1e-45", "nan", "inf", "-inf", "abc", "$", "$nothere", "$res", "1.5",
        "9223372036854775807", "99999999999999999999", "0, 0, 0", "1 2", "1,2,3,4", "true", "diffuse", "white", "perspective",
        "../../nothere.obj", "\u{3bb}",
    ];
    let mut starts = vec![];
    let mut rest = 0;
    while let Some(i) = text[rest..].find("=\"") {
        let start = rest + i + 2;
        let end = start + text[start..].find('"').unwrap();
        starts.push((start, end));
        rest = end + 1;
    }
    assert!(starts.len() > 100, "found {} attribute values", starts.len());
    for &(start, end) in &starts {
        for v in values {
            let corrupted = format!("{}{v}{}", &text[..start], &text[end..]);
            load_never_panics(&path, corrupted.as_bytes(), &params, &mut seen);
        }
    }
    // Extreme -D values for the declared parameters.
    for v in values {
        for key in ["res", "spp", "max_depth"] {
            let mut p = params.clone();
            p.insert(key.to_string(), v.to_string());
            load_never_panics(&path, &original, &p, &mut seen);
        }
    }
    assert!(seen.1 > seen.0, "most corruptions should be errors: {seen:?}");
}

#[test]
fn stray_text_points_at_the_text() {
    let e = load_err(&scene("    <shape type=\"sphere\">\n        hello\n    </shape>\n"));
    assert_error(&e, &scene_path(), 10, 9, "hello", "unexpected text inside an element");
    let e = load_err(&scene(
        "    <shape type=\"sphere\">\n        <transform name=\"to_world\">\n            oops\n        </transform>\n    </shape>\n",
    ));
    assert_error(&e, &scene_path(), 11, 13, "oops", "unexpected text inside <transform>");
}

#[test]
fn byte_order_mark_and_crlf_do_not_shift_columns() {
    let e = load_err("\u{feff}<scene version=\"3.0.0\"><foo/>\n</scene>\n");
    assert_error(&e, &scene_path(), 1, 24, "<foo/>", "unknown element <foo>");
    let e = load_err("\u{feff}<scene version=\"3.0.0\">\n</scene>\n");
    assert_error(&e, &scene_path(), 1, 1, "<scene", "the scene has no <sensor>");
    let text = scene("    <shape type=\"sphere\">\n        <float name=\"radius2\" value=\"1\"/>\n    </shape>\n").replace('\n', "\r\n");
    let e = load_err(&text);
    assert_error(&e, &scene_path(), 10, 9, "<float", "unused parameter \"radius2\"");
    assert!(!e.to_string().contains('\r'), "{e:?}");
}

#[test]
fn duplicated_attribute() {
    let e = load_err(&scene("    <shape type=\"sphere\">\n        <float name=\"radius\" value=\"1\" value=\"2\"/>\n    </shape>\n"));
    assert_error(&e, &scene_path(), 10, 40, "value=\"2\"", "malformed XML: attribute 'value'");
}

// ------------------------------------------------------- rough BSDFs (issue 12)

#[test]
fn rough_bsdf_parameter_errors_are_located() {
    // An unknown distribution lists the two there are.
    let e = load_err(&scene("    <bsdf type=\"roughconductor\">\n        <string name=\"distribution\" value=\"phong\"/>\n    </bsdf>\n"));
    assert_error(&e, &scene_path(), 10, 9, "<string name=\"distribution\"", "distribution");
    assert_help(&e, &["beckmann, ggx"]);
    // alpha together with alpha_u/alpha_v.
    let e = load_err(&scene(
        "    <bsdf type=\"roughdielectric\">\n        <float name=\"alpha\" value=\"0.1\"/>\n        <float name=\"alpha_u\" value=\"0.1\"/>\n        <float name=\"alpha_v\" value=\"0.2\"/>\n    </bsdf>\n",
    ));
    assert_error(&e, &scene_path(), 10, 9, "<float name=\"alpha\"", "not both");
    // alpha_u without alpha_v.
    let e = load_err(&scene("    <bsdf type=\"roughconductor\">\n        <float name=\"alpha_u\" value=\"0.1\"/>\n    </bsdf>\n"));
    assert_error(&e, &scene_path(), 9, 5, "<bsdf", "\"alpha_v\" is missing");
    // A negative roughness.
    let e = load_err(&scene("    <bsdf type=\"roughconductor\">\n        <float name=\"alpha\" value=\"-0.1\"/>\n    </bsdf>\n"));
    assert_error(&e, &scene_path(), 10, 9, "<float name=\"alpha\"", "non-negative");
}

#[test]
fn roughplastic_parameter_errors_are_located() {
    // Mitsuba 3.9.1's roughplastic takes a float alpha only (its tables depend on it).
    let e = load_err(&scene(
        "    <bsdf type=\"roughplastic\">\n        <texture type=\"checkerboard\" name=\"alpha\"/>\n    </bsdf>\n",
    ));
    assert_error(&e, &scene_path(), 9, 5, "<bsdf type=\"roughplastic\"", "must be a float");
    // And is isotropic.
    let e = load_err(&scene("    <bsdf type=\"roughplastic\">\n        <float name=\"alpha_u\" value=\"0.1\"/>\n    </bsdf>\n"));
    assert_error(&e, &scene_path(), 10, 9, "<float name=\"alpha_u\"", "isotropic");
    // A negative roughness, an unknown distribution, equal indices.
    let e = load_err(&scene("    <bsdf type=\"roughplastic\">\n        <float name=\"alpha\" value=\"-0.1\"/>\n    </bsdf>\n"));
    assert_error(&e, &scene_path(), 10, 9, "<float name=\"alpha\"", "non-negative");
    let e = load_err(&scene("    <bsdf type=\"roughplastic\">\n        <string name=\"distribution\" value=\"phong\"/>\n    </bsdf>\n"));
    assert_help(&e, &["beckmann, ggx"]);
    let e = load_err(&scene("    <bsdf type=\"roughplastic\">\n        <float name=\"int_ior\" value=\"1.5\"/>\n        <float name=\"ext_ior\" value=\"1.5\"/>\n    </bsdf>\n"));
    assert_error(&e, &scene_path(), 10, 9, "<float name=\"int_ior\"", "must differ");
}

#[test]
fn principled_parameter_errors_are_located() {
    // Mitsuba 3.9.1 refuses both "eta" and "specular" (one sets the other).
    let e = load_err(&scene(
        "    <bsdf type=\"principled\">\n        <float name=\"eta\" value=\"1.5\"/>\n        <float name=\"specular\" value=\"0.3\"/>\n    </bsdf>\n",
    ));
    assert_error(&e, &scene_path(), 11, 9, "<float name=\"specular\"", "either \"eta\" or \"specular\"");
    let e = load_err(&scene("    <bsdf type=\"principled\">\n        <float name=\"eta\" value=\"-1\"/>\n    </bsdf>\n"));
    assert_error(&e, &scene_path(), 10, 9, "<float name=\"eta\"", "positive");
    let e = load_err(&scene("    <bsdf type=\"principledthin\">\n        <float name=\"diffuse_reflectance_sampling_rate\" value=\"-1\"/>\n    </bsdf>\n"));
    assert_error(&e, &scene_path(), 10, 9, "<float name=\"diffuse_reflectance_sampling_rate\"", "non-negative");
    // A misspelt parameter is unused, as for every plugin.
    let e = load_err(&scene("    <bsdf type=\"principled\">\n        <float name=\"metalic\" value=\"1\"/>\n    </bsdf>\n"));
    assert_error(&e, &scene_path(), 10, 9, "<float name=\"metalic\"", "metalic");
}

// ------------------------------------------------------- spectrum plugins

#[test]
fn spectrum_plugin_errors_are_located_and_list_the_choices() {
    let shape = |spectrum: &str| scene(&format!("    <shape type=\"sphere\"><bsdf type=\"diffuse\">\n        {spectrum}\n    </bsdf></shape>\n"));
    // An unknown plugin: at its type attribute, with the six Mitsuba knows.
    let e = load_err(&shape(r#"<spectrum type="planck" name="reflectance"/>"#));
    assert_error(&e, &scene_path(), 10, 19, "type=", "unknown spectrum plugin \"planck\"");
    assert_help(&e, &["blackbody", "d65", "irregular", "regular", "srgb", "uniform"]);
    // An unknown parameter: at the property, with the plugin's parameters.
    let e = load_err(&shape(r#"<spectrum type="blackbody" name="reflectance"><float name="lambda_min" value="400"/></spectrum>"#));
    assert_error(&e, &scene_path(), 10, 55, "<float", "unknown parameter \"lambda_min\"");
    assert_help(&e, &["temperature", "wavelength_min", "wavelength_max"]);
    // A missing parameter: at the <spectrum>.
    let e = load_err(&shape(r#"<spectrum type="blackbody" name="reflectance"/>"#));
    assert_error(&e, &scene_path(), 10, 9, "<spectrum", "needs the parameter \"temperature\"");
    // Lists that do not match.
    let e = load_err(&shape(
        r#"<spectrum type="irregular" name="reflectance"><string name="wavelengths" value="400, 500"/><string name="values" value="0.1, 0.2, 0.3"/></spectrum>"#,
    ));
    assert_error(&e, &scene_path(), 10, 9, "<spectrum", "as many values as wavelengths");
    let e = load_err(&shape(
        r#"<spectrum type="regular" name="reflectance"><float name="wavelength_min" value="400"/><float name="wavelength_max" value="700"/><string name="values" value="0.1, x"/></spectrum>"#,
    ));
    assert_error(&e, &scene_path(), 10, 137, "<string", "not a list of numbers");
    // An sRGB colour above one needs `unbounded`, as in Mitsuba.
    let e = load_err(&shape(r#"<spectrum type="srgb" name="reflectance"><rgb name="color" value="2, 0.5, 0.5"/></spectrum>"#));
    assert_error(&e, &scene_path(), 10, 50, "<rgb", "must lie in [0, 1]");
    assert_help(&e, &["unbounded"]);
    // A wrong type: a temperature given as a string.
    let e = load_err(&shape(r#"<spectrum type="blackbody" name="reflectance"><string name="temperature" value="hot"/></spectrum>"#));
    assert_error(&e, &scene_path(), 10, 55, "<string", "must be a float, not string");
    // A non-positive temperature.
    let e = load_err(&shape(r#"<spectrum type="blackbody" name="reflectance"><float name="temperature" value="-5"/></spectrum>"#));
    assert_error(&e, &scene_path(), 10, 9, "<spectrum", "temperature must be positive");
}
