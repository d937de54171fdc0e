//! The evaluation harness behind `animcodec eval`, `animcodec sweep` and
//! `animcodec encode --target`: rate-ladder sweeps, rate-distortion tables and plots, and
//! target-error search. Everything here works on in-memory [`Animation`](codec_core::Animation)s
//! or on inputs read frame by frame ([`InputSource`]), so it can be tested without the binary.
//!
//! Modules by job, each importing only those above it in this list:
//!
//! * `point`: [`measure_point`] encodes one animation at one parameter set,
//!   decodes the stream (the decoder sees nothing but the bytes) and measures it with
//!   [`metrics::evaluate`]; [`ladder_indices`] and [`ladder_params`] pick ladder steps.
//! * `target`: [`Target`] (`kg=0.5`), what a search found ([`TargetHit`]) or missed
//!   ([`TargetMiss`]), and which points are [`usable`].
//! * `curve`: [`monotone_report`] (bpvf rises and the errors fall along each ladder) and each
//!   codec's lower [`envelope`].
//! * `refine`: where the envelope sweep measures next toward the [`STANDARD_TARGETS`] (the
//!   targets the field compares codecs at), and the bracket rules the space search shares.
//! * `sweep`: [`sweep`] walks the rate ladder of every series, in parallel with rayon or
//!   sequentially (`jobs = 1`, for timing), and returns the rows sorted by series then ladder
//!   position whatever the scheduling; [`sweep_point`] is one job of it; [`envelope_sweep`]
//!   the default sweep over each codec's declared search space.
//! * `rows`: [`SweepRow`] and [`SweepDocument`], the serde types `sweep --json` and
//!   `sweep --csv` write ([`csv_text`]), and rows read back ([`points_from_rows`]).
//! * `search`: [`SearchRequest`], and [`search_target`] along one rate ladder
//!   ([`search_target_auto`]: over several codecs).
//! * `space`: [`search_space_target`] over a codec's declared search space
//!   ([`search_space_target_auto`]).
//! * `default_quality`: [`search_default_quality`], the default encode's short search.
//! * `streamed`: [`measure_stream`] measures an `.anim` stream packet by packet against a
//!   reference read frame by frame ([`FrameSource`]), [`measure_sources`] two sides read so,
//!   in the bounded memory of [`metrics::StreamingEvaluator`].
//! * `input`: what a search measures against ([`SearchInput`]): the whole animation, or a
//!   [`InputSource`] read frame by frame within a memory budget ([`StreamedInput`],
//!   [`measure_point_streamed`]).
//! * `sample`: [`SampledSource`], windows of whole temporal blocks of a film-size input, for a
//!   search whose candidates each cost a fraction of a pass.

mod csv;
mod curve;
mod default_quality;
mod input;
mod measured;
mod point;
mod refine;
mod rows;
mod sample;
mod search;
mod space;
mod streamed;
mod sweep;
pub(crate) mod target;

pub use curve::{envelope, joint_envelope, monotone_report, Monotonicity};
pub use default_quality::{
    search_default_quality, BEYOND_LADDER_STEPS, DEFAULT_QUALITY_BAND, DEFAULT_REFINE_BAND, DEFAULT_TARGET,
};
pub use input::{
    encode_source, encoder_need, least_streamed_budget, least_work_budget, measure_point_streamed,
    measure_stream_against, measurement_limits, whole_search_need, work_share, CacheSource, FrameRead, InputSource,
    SearchInput, StreamedInput, MIN_STREAM_SHARE, STREAM_SHARE_DIVISOR,
};
pub use measured::Point;
pub use point::{ladder_indices, ladder_params, measure_point, measure_point_keeping};
pub use refine::{CONFIGS_PER_TARGET, REFINE_ROUNDS, STANDARD_TARGETS};
pub use rows::{
    csv_columns, csv_text, points_from_rows, report_json, write_text, Envelopes, FailureRow, SweepDocument, SweepRow,
};
pub use sample::{
    scaled_target, SampledSource, MIN_SAMPLE_WINDOWS, MIN_WINDOW_FRAMES, SAMPLE_SHARE, SAMPLE_TARGET_MARGIN,
    UNALIGNED_SAMPLE_BLOCK,
};
pub use search::{search_target, search_target_auto, SearchRequest};
pub use space::{search_space_target, search_space_target_auto};
pub use streamed::{chunk_frames, measure_bytes_held, measure_sources, measure_stream, FrameSource, CHUNK_BYTES};
pub use sweep::{
    envelope_sweep, sweep, sweep_jobs, sweep_point, Failure, Sweep, SweepEvent, SweepOptions, SweepSeries,
};
pub use target::{
    sted_degenerate, usable, Target, TargetHit, TargetMetric, TargetMiss, DEGENERATE_KG, STED_DEGENERATE_KG,
};

/// What every harness function fails with (matched by variant: a search that found nothing is
/// [`EvalError::TargetMiss`]).
pub use crate::error::{EvalError, Result};

#[cfg(test)]
mod tests {
    use super::search::midpoint;
    use super::*;
    use crate::error::EvalError;
    use animcodec_synth as synth;
    use codec_core::{CodecRegistry, ParamValue};
    use serde_json::Value;

    /// The harness takes its codecs from the caller; these tests use the baseline and one
    /// transform codec (the facade crate's `registry()` is above this crate).
    fn test_registry() -> CodecRegistry {
        CodecRegistry::new(vec![Box::new(codec_quant_delta::QuantDelta), Box::new(codec_pca_aoi::PcaAoi)])
            .expect("unique codec names")
    }

    #[test]
    fn ladder_indices_spread_evenly_and_keep_ends() {
        assert_eq!(ladder_indices(9, None), (0..9).collect::<Vec<_>>());
        assert_eq!(ladder_indices(9, Some(20)), (0..9).collect::<Vec<_>>());
        assert_eq!(ladder_indices(9, Some(3)), vec![0, 4, 8]);
        assert_eq!(ladder_indices(9, Some(2)), vec![0, 8]);
        assert_eq!(ladder_indices(9, Some(1)), vec![8]);
        assert_eq!(ladder_indices(0, Some(3)), Vec::<usize>::new());
        for len in 2..30 {
            for n in 2..len {
                let v = ladder_indices(len, Some(n));
                assert_eq!(v.len(), n, "len {len} n {n}");
                assert_eq!((v[0], v[n - 1]), (0, len - 1));
                assert!(v.windows(2).all(|w| w[0] < w[1]));
            }
        }
    }

    #[test]
    fn midpoints_are_rounded_and_stop_when_the_bracket_closes() {
        let f = |x| ParamValue::Float(x);
        assert_eq!(midpoint(&f(0.9), &f(0.85)), Some(f(0.875)));
        assert_eq!(midpoint(&f(0.9), &f(0.875)), Some(f(0.8875)));
        assert_eq!(midpoint(&f(0.8968), &f(0.8969)), Some(f(0.89685)));
        assert_eq!(midpoint(&f(1.0), &f(1.0)), None);
        assert_eq!(midpoint(&ParamValue::Int(6), &ParamValue::Int(8)), Some(ParamValue::Int(7)));
        assert_eq!(midpoint(&ParamValue::Int(8), &ParamValue::Int(7)), None);
        assert_eq!(midpoint(&ParamValue::Int(250), &ParamValue::Int(160)), Some(ParamValue::Int(205)));
        assert_eq!(midpoint(&ParamValue::Bool(false), &ParamValue::Bool(true)), None);
    }

    #[test]
    fn targets_parse() {
        assert_eq!("kg=0.5".parse::<Target>().unwrap(), Target::new(TargetMetric::Kg, 0.5));
        assert_eq!("max-error=1e-3".parse::<Target>().unwrap().single().unwrap().0, TargetMetric::MaxError);
        assert_eq!("STED = 0.01".parse::<Target>().unwrap().bound(TargetMetric::Sted), Some(0.01));
        assert!("kg".parse::<Target>().unwrap_err().contains("METRIC=VALUE"));
        assert!("psnr=3".parse::<Target>().unwrap_err().contains("kg, sted, hausdorff"));
        assert!("kg=-1".parse::<Target>().is_err());
        assert!("kg=nan".parse::<Target>().is_err());
        assert!("kg=x".parse::<Target>().is_err());
        // Joint targets: every bound, printed in a fixed order, each metric once.
        let joint: Target = "sted=0.05, kg=0.5".parse().unwrap();
        assert_eq!(joint, Target::new(TargetMetric::Kg, 0.5).and_bound(TargetMetric::Sted, 0.05));
        assert_eq!(joint.to_string(), "kg=0.5,sted=0.05");
        assert_eq!(joint.to_string().parse::<Target>().unwrap(), joint);
        assert_eq!(joint.single(), None);
        assert!("kg=0.5,kg=0.1".parse::<Target>().unwrap_err().contains("kg is bounded twice"));
        assert!("kg=0.5,".parse::<Target>().is_err());
        let kg: Target = "kg=0.5".parse().unwrap();
        assert_eq!(kg.and("sted=0.05".parse().unwrap()).unwrap(), joint);
        assert!(joint.and(kg).is_err());
        assert_eq!(joint.distortion_kind(), codec_core::DistortionKind::Both);
        assert_eq!(kg.distortion_kind(), codec_core::DistortionKind::Position);
        assert_eq!("sted=1".parse::<Target>().unwrap().distortion_kind(), codec_core::DistortionKind::Shape);
    }

    #[test]
    fn a_joint_target_is_met_only_when_every_bound_is_and_its_error_is_the_binding_ratio() {
        let joint: Target = "kg=0.5,sted=0.05".parse().unwrap();
        let a = synth::tumbling_body_sized(8, 6, 4);
        let exact = metrics::evaluate(&a, &a, &metrics::EvalOptions::default()).unwrap();
        // No worst part: KG is the whole animation's.
        let report = |kg: f64, sted: Option<f64>| metrics::MetricReport {
            kg: Some(kg),
            sted,
            worst_part: None,
            ..exact.clone()
        };
        assert!(joint.meets(&report(0.5, Some(0.05))));
        assert!(!joint.meets(&report(0.4, Some(0.06))));
        assert!(!joint.meets(&report(0.6, Some(0.01))));
        // STED not computed: not met (never assumed).
        assert!(!joint.meets(&report(0.1, None)));
        assert_eq!(joint.error(&report(0.1, None)), None);
        // The binding bound's ratio: KG at 0.8 of its bound, STED at 1.2 of its bound.
        let e = joint.error(&report(0.4, Some(0.06))).unwrap();
        assert!((e - 1.2).abs() < 1e-12, "{e}");
        assert_eq!(joint.level(), 1.0);
        // One bound: the metric itself, so single-metric searches are unchanged.
        let kg: Target = "kg=0.5".parse().unwrap();
        assert_eq!(kg.error(&report(0.4, Some(0.06))), Some(0.4));
        assert_eq!(kg.level(), 0.5);
        assert!(joint.eval_options(&metrics::EvalOptions::default()).compute_sted);
        assert!(!kg.eval_options(&metrics::EvalOptions::default()).compute_sted);
        assert_eq!(joint.reached_text(&report(0.4, Some(0.06)), 2), "kg=0.40, sted=0.06");
    }

    #[test]
    fn sweep_points_and_rows_read_back_give_the_sweep_rows() {
        let registry = test_registry();
        let a = synth::tumbling_body_sized(8, 6, 4);
        let series: Vec<SweepSeries<'_>> = registry.iter().take(2).map(SweepSeries::defaults).collect();
        let options = SweepOptions { points: Some(2), jobs: Some(1), ..Default::default() };
        let swept = sweep(&registry, &series, &a, &options, &|_| {}).unwrap();
        assert_eq!(swept.points.len(), 4);
        let without_timings = |p: &Point| {
            let mut v = SweepRow::from(p).to_json();
            v["encode_seconds"] = Value::Null;
            v["decode_seconds"] = Value::Null;
            v
        };
        // One job on its own measures what the sweep measured at that point.
        for (p, &(c, step)) in swept.points.iter().zip(&sweep_jobs(&series, options.points)) {
            let alone = sweep_point(&registry, &series[c], step, &a, &options).unwrap();
            assert_eq!(without_timings(&alone), without_timings(p));
        }
        // Rows gathered elsewhere come back as the same rows, table and document.
        let dims = (a.vertex_count(), a.frame_count());
        let rows: Vec<Value> = swept.points.iter().map(|p| SweepRow::from(p).to_json()).collect();
        let back = points_from_rows(&registry, &rows, &options.eval, dims).unwrap();
        assert_eq!(back.iter().map(|p| SweepRow::from(p).to_json()).collect::<Vec<_>>(), rows);
        assert_eq!(csv_text(&back).unwrap(), csv_text(&swept.points).unwrap());
        let rebuilt = Sweep { points: back, ..Sweep::default() };
        assert_eq!(
            SweepDocument::new("x", dims, &options.eval, &rebuilt).to_json().unwrap(),
            SweepDocument::new("x", dims, &options.eval, &swept).to_json().unwrap()
        );
        let mut broken = rows.clone();
        broken[1].as_object_mut().unwrap().remove("bpvf");
        let e = points_from_rows(&registry, &broken, &options.eval, dims).unwrap_err().to_string();
        assert!(e.contains("'bpvf' is missing") && e.contains("row 1"), "{e}");
    }

    /// The CSV is the rows' own serialization: the old hand-written writer's document, byte for
    /// byte (its header, `key=value;…` parameters in the codec's order, empty cells for missing
    /// metrics, `Display` numbers, a quoted series label).
    #[test]
    fn csv_lines_are_the_rows_in_column_order() {
        let registry = test_registry();
        let a = synth::tumbling_body_sized(8, 6, 4);
        let codec = registry.by_name("pca-aoi").unwrap();
        let base = codec.default_params();
        let ladder = codec.rate_ladder(&base);
        let params = ladder_params(codec, &base, &ladder, 0).unwrap();
        let eval = metrics::EvalOptions { compute_sted: false, ..Default::default() };
        let (mut p, _) =
            measure_point(&registry, codec, &params, (ladder.param, 0), &a, &eval, codec_core::Limits::default())
                .unwrap();
        p.series = "pca-aoi[a=1,b=\"2\"]".into();
        p.encode_seconds = 100.0;
        p.decode_seconds = 0.000031;
        let text = csv_text(&[p.clone()]).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(
            lines[0],
            "codec,series,params,ladder_index,bytes,bpvf,kg,sted,sted_spatial,sted_temporal,hausdorff,\
             hausdorff_relative,mse,rmse,max_error,parts,worst_part_kg,encode_seconds,decode_seconds"
        );
        let r = &p.report;
        let params: Vec<String> = p.params.iter().map(|(n, v)| format!("{n}={v}")).collect();
        let opt = |v: Option<f64>| v.map(|x| format!("{x}")).unwrap_or_default();
        let expected = [
            "pca-aoi".to_string(),
            "\"pca-aoi[a=1,b=\"\"2\"\"]\"".to_string(),
            params.join(";"),
            "0".into(),
            p.bytes.to_string(),
            format!("{}", p.bpvf),
            opt(r.kg),
            opt(r.sted),
            opt(r.sted_spatial),
            opt(r.sted_temporal),
            opt(r.hausdorff),
            opt(r.hausdorff_relative),
            format!("{}", r.mse),
            format!("{}", r.rmse),
            format!("{}", r.max_error),
            r.parts.to_string(),
            opt(r.worst_part_kg()),
            "100".into(),
            "0.000031".into(),
        ];
        assert_eq!(lines[1], expected.join(","));
        assert!(r.sted.is_none(), "STED was not computed: an empty cell");
    }

    #[test]
    fn miss_reports_the_best_point() {
        let registry = test_registry();
        let codec = registry.by_name("quant-delta").unwrap();
        let a = synth::tumbling_body_sized(8, 6, 4);
        let target = Target::new(TargetMetric::MaxError, 0.0);
        let e = search_target(&SearchRequest::new(&registry, &a, target), codec, &codec.default_params()).unwrap_err();
        let EvalError::TargetMiss(miss) = e else { panic!("expected a TargetMiss, got {e}") };
        let top = codec.rate_ladder(&codec.default_params()).steps.len() - 1;
        assert_eq!(miss.best.as_ref().unwrap().ladder_index, top);
        let text = miss.to_string();
        assert!(text.contains("best reached is max_error=") && text.contains("quant-delta"), "{text}");
    }
}

/// The default quality and `kg=` targets hold for every part, not only for the whole scene a
/// large static part dominates (probe small-object-destroyed).
#[cfg(test)]
mod parts_tests {
    use super::*;
    use codec_core::{Animation, CodecRegistry};

    fn registry() -> CodecRegistry {
        CodecRegistry::new(vec![Box::new(codec_quant_delta::QuantDelta), Box::new(codec_pca_aoi::PcaAoi)])
            .expect("unique codec names")
    }

    /// A deforming `n × n` unit plane (the probe's body) beside a static square of side
    /// `floor` centred at `(offset, 0, -0.5)`, `frames` frames.
    pub(crate) fn scene(n: usize, frames: usize, floor: f32, offset: f32) -> Animation {
        let mut tris = Vec::new();
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let a = (j * n + i) as u32;
                tris.push([a, a + 1, a + n as u32 + 1]);
                tris.push([a, a + n as u32 + 1, a + n as u32]);
            }
        }
        let b = (n * n) as u32;
        tris.extend([[b, b + 1, b + 2], [b, b + 2, b + 3]]);
        let h = floor / 2.0;
        let square = [[-h, -h], [h, -h], [h, h], [-h, h]];
        let mut positions = Vec::new();
        for t in 0..frames {
            for j in 0..n {
                for i in 0..n {
                    let (x, y) = (i as f32 / (n - 1) as f32, j as f32 / (n - 1) as f32);
                    let phase = std::f32::consts::TAU * t as f32 / frames as f32;
                    positions.extend([x, y, 0.3 * (3.0 * x + phase).sin() * (2.0 * y).cos()]);
                }
            }
            for [x, y] in square {
                positions.extend([offset + x, y, -0.5]);
            }
        }
        Animation::from_parts(n * n + 4, tris, positions, 30.0).unwrap()
    }

    #[test]
    fn the_default_quality_holds_for_the_small_part() {
        let registry = registry();
        // The probe's ground plane (1000 × 1000 beside a 1 × 1 body) and a far copy of it.
        for (floor, offset) in [(1000.0, 0.0), (1.0, 1.0e4)] {
            let a = scene(12, 16, floor, offset);
            for codec in registry.iter() {
                let request = SearchRequest::default_quality(&registry, &a);
                match search_default_quality(&request, codec) {
                    Ok(hit) => {
                        let r = &hit.point.report;
                        let worst = r.worst_part.as_ref().expect("two parts");
                        assert_eq!(r.parts, 2);
                        assert_eq!(worst.first_vertex, 0, "the body is the worst part: {worst:?}");
                        assert!(
                            worst.kg.unwrap() <= DEFAULT_TARGET.bound(TargetMetric::Kg).unwrap(),
                            "{}: {worst:?}",
                            codec.name()
                        );
                        assert!(r.kg.unwrap() < worst.kg.unwrap(), "the scene's KG hides the body's");
                        // The report is the measurement of the stream itself.
                        let decoded = codec_core::StreamDecoder::new(
                            hit.stream.as_slice(),
                            &registry,
                            codec_core::Limits::default(),
                        )
                        .unwrap()
                        .decode_all()
                        .unwrap();
                        let (_, errors) = metrics::part_errors(&a, &decoded).unwrap();
                        assert_eq!(errors[0].kg, worst.kg);
                    }
                    // Missing the target is an honest answer; the message names the part.
                    Err(EvalError::TargetMiss(miss)) => {
                        let text = miss.to_string();
                        assert!(text.contains("kg="), "{text}");
                    }
                    Err(e) => panic!("{}: {e}", codec.name()),
                }
            }
        }
    }

    #[test]
    fn a_kg_target_is_the_worst_part() {
        let a = scene(8, 6, 1000.0, 0.0);
        let registry = registry();
        let codec = registry.by_name("quant-delta").unwrap();
        let target = Target::new(TargetMetric::Kg, 1.0);
        let hit = search_target(&SearchRequest::new(&registry, &a, target), codec, &codec.default_params()).unwrap();
        let r = &hit.point.report;
        assert!(r.worst_part_kg().unwrap() <= 1.0 && r.kg_bound() == r.worst_part_kg(), "{r:?}");
        assert_eq!(target.error(r), r.worst_part_kg());
    }
}
