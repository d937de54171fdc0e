//! Every registered codec's parameters, through the object-safe trait only: each spec's
//! default is legal and is what `default_params` holds; every legal value (default, range
//! ends, every choice) prints and parses back to itself and is accepted into a parameter set
//! that the codec then validates or refuses by name (a cross-field rule, e.g. hosvd's `v`
//! without `f`); every illegal value is refused, naming codec and parameter. The typed side
//! (`ParamSet → struct → ParamSet` for the same values) is checked in each codec crate by
//! `codec_core::testing::check_declared_params`.

use codec_core::testing::{illegal_values, legal_values};
use codec_core::ParamSet;

#[test]
fn every_codec_parameter_prints_parses_and_validates_consistently() {
    let registry = animcodec::registry();
    for codec in registry.iter() {
        let name = codec.name();
        let specs = codec.param_specs();
        let defaults = codec.default_params();
        assert_eq!(defaults, ParamSet::defaults(name, &specs), "{name}");
        codec.validate(&defaults).unwrap_or_else(|e| panic!("{name}: defaults refused: {e}"));
        for spec in &specs {
            let param = spec.name;
            assert_eq!(defaults.get(param), Some(&spec.default), "{name}.{param}");
            for value in legal_values(spec) {
                let text = value.to_string();
                assert_eq!(spec.parse(name, &text).ok(), Some(value.clone()), "{name}.{param}='{text}'");
                let set = defaults.clone().with(&specs, param, value).unwrap_or_else(|e| panic!("{name}: {e}"));
                if let Err(e) = codec.validate(&set) {
                    let e = e.to_string();
                    assert!(e.contains(name), "{name}.{param}='{text}' refused without naming the codec: {e}");
                }
            }
            for value in illegal_values(spec) {
                let e = defaults.clone().with(&specs, param, value.clone()).expect_err(&format!("{name}.{param}"));
                let e = e.to_string();
                assert!(e.contains(name) && e.contains(param), "{name}.{param}={value}: {e}");
                assert!(spec.parse(name, &value.to_string()).is_err(), "{name}.{param}: '{value}' parsed");
            }
        }
    }
}
