//! `encode` with a target or the default quality: the input read whole or opened frame by frame
//! within the memory budget, the search, and the chosen stream written and reported.

use super::*;

/// The document of `encode --json` with a target (or the default quality).
#[derive(Debug, Serialize)]
pub struct TargetEncodeDocument<'a> {
    /// What the search found.
    #[serde(flatten)]
    pub summary: TargetSummary,
    /// The input as given.
    pub input: &'a str,
    /// The stream written.
    pub output: String,
    /// Whether the target is the default quality (no -p, no --target).
    pub default_target: bool,
    /// `space` or `ladder`.
    pub search: &'static str,
    /// The chosen encode's warnings and remarks.
    pub notes: Vec<String>,
    /// How the search read the input: `whole` (the animation in memory), `streamed` (each
    /// candidate encoded from the input as it is read and measured against a second read) or
    /// `sampled` (streamed, the candidates measured on a sample of its frames, then the chosen
    /// parameters encoded over the whole input and measured: `reached`, `bytes` and the
    /// evaluation are the whole stream's, `tried` the sample's).
    pub search_input: &'static str,
    /// A sampled search's sample, in frames (`null` otherwise).
    pub sample_frames: Option<usize>,
    /// How many times a sampled search encoded the whole input: 1, or more when the whole
    /// missed the target and the sample was searched again aiming lower (`null` otherwise).
    pub whole_encodes: Option<usize>,
    /// The memory budget the search kept to (bytes): for an input over
    /// [`front::WHOLE_SEARCH_MAX_RAW`], [`front::streamed_search_budget`]; else `--memory`, or
    /// the default share of the machine's RAM; `null` when none applies.
    pub memory_budget: Option<u64>,
    /// Whether no `--memory` was given (the cap is the default share of the RAM).
    pub memory_budget_default: bool,
    /// Raw f32 size over the stream's.
    pub ratio: f64,
    /// Frames.
    pub frames: usize,
    /// Vertices per frame.
    pub vertices: usize,
    /// Triangles.
    pub triangles: usize,
    /// Frames per second.
    pub frame_rate: f32,
    /// Seconds reading the input.
    pub read_seconds: f64,
    /// Seconds searching.
    pub search_seconds: f64,
    /// Seconds encoding the chosen point.
    pub encode_seconds: f64,
    /// `--eval`'s figures.
    #[serde(flatten)]
    pub evaluation: Option<EvaluationFields>,
}

/// What a search reads: the whole animation, or a source read frame by frame.
enum SearchSource {
    Whole(Animation),
    Streamed(Box<dyn InputSource>),
}

/// A search's input and its memory budget, and the note saying why it streams.
struct PreparedInput {
    input: SearchSource,
    budget: Option<u64>,
    note: Option<String>,
}

/// Reads (or opens) a search's input under the memory budget: `--memory`, else
/// [`front::default_memory_budget`]. An input that can be read frame by frame (PC2, MDD, an
/// OBJ sequence, `synth:flag:COLSxROWSxFRAMES`) is searched whole while it is small
/// ([`front::WHOLE_SEARCH_MAX_RAW`]) and the whole-array search fits the budget by
/// [`harness::whole_search_need`] (the largest over `codecs`); a larger one streams within
/// [`front::streamed_search_budget`] (twice its raw size by the codecs' models, capped by the budget), one that
/// does not fit streams within the budget, each with a note saying so. Any other input is read
/// whole; beyond an explicit `--memory` it is refused.
fn prepare_search_input(
    args: &EncodeArgs,
    codecs: &[(&dyn AnimationCodec, ParamSet)],
    eval: &EvalOptions,
    limits: Limits,
) -> CmdResult<PreparedInput> {
    let (budget, given) = match args.memory {
        Some(m) => (Some(m), true),
        None => (front::default_memory_budget(), false),
    };
    let options = args.read.options(args.fps);
    let need = |v: usize, f: usize| codecs.iter().map(|(c, _)| harness::whole_search_need(*c, v, f)).max().unwrap_or(0);
    if let Some((cols, rows, _)) = front::streamed_flag(&args.input)? {
        check_flag_memory(&args.input, cols, rows, args.memory)?;
    }
    let source = crate::commands::source::streamable(&args.input, &options, args.fps)?;
    let Some(source) = source else {
        let animation = load(&args.input, &options, limits, Streams::Refuse)?.animation;
        let whole = need(animation.vertex_count(), animation.frame_count());
        if let (Some(b), true) = (budget, given) {
            if whole > b {
                return Err(format!(
                    "{}: a search over this input holds it whole (only .pc2/.mdd caches, OBJ sequences and \
                     synth:flag:COLSxROWSxFRAMES are read frame by frame), about {} MiB, more than --memory {} MiB; \
                     convert it to a PC2 cache (animcodec export) or give a larger --memory",
                    args.input,
                    whole >> 20,
                    b >> 20
                )
                .into());
            }
        }
        return Ok(PreparedInput { input: SearchSource::Whole(animation), budget, note: None });
    };
    let (v, f) = (source.topology().vertex_count(), source.frame_count());
    let whole = need(v, f);
    let raw = (v as u64).saturating_mul(f as u64).saturating_mul(12);
    // The least budget every searched codec streams in (a codec that cannot stream at all is
    // refused or left out later, naming it) and the streamed search's own floor.
    let least = codecs
        .iter()
        .filter_map(|(c, p)| harness::least_streamed_budget(*c, p, v, f))
        .max()
        .unwrap_or(0)
        .max(StreamedInput::least_budget(source.topology(), eval));
    if let Some(b) = front::streamed_search_budget(raw, budget, least) {
        let (num, den) = front::STREAMED_SEARCH_SHARE_OF_RAW;
        let note = format!(
            "{} is {} MiB of coordinates: the search streams it within {} MiB ({num}/{den} of that{}{}) rather than \
             holding it whole (about {} MiB); each candidate is encoded from the input as it is read and measured \
             against a second read",
            args.input,
            raw >> 20,
            b >> 20,
            if least > raw / den * num { ", raised to the least the codec's blocks allow" } else { "" },
            match (budget, given) {
                (Some(cap), true) if cap < raw / den * num => ", capped by --memory",
                (Some(cap), false) if cap < raw / den * num => ", capped by the default memory budget",
                _ => "",
            },
            whole.min(u64::MAX >> 1) >> 20
        );
        return Ok(PreparedInput { input: SearchSource::Streamed(source), budget: Some(b), note: Some(note) });
    }
    match budget {
        Some(b) if whole > b => {
            let whose = if given {
                format!("--memory {} MiB", b >> 20)
            } else {
                format!(
                    "the default memory budget, {} MiB ({} of this machine's RAM; --memory sets it, and the \
                     codec's blocks may depend on it)",
                    b >> 20,
                    if front::DEFAULT_MEMORY_SHARE == (1, 2) {
                        "half".to_owned()
                    } else {
                        format!("{:?}", front::DEFAULT_MEMORY_SHARE)
                    }
                )
            };
            let note = format!(
                "a search over the whole of {} would hold about {} MiB, more than {whose}: it streams instead \
                 (each candidate is encoded from the input as it is read and measured against a second read)",
                args.input,
                whole >> 20
            );
            Ok(PreparedInput { input: SearchSource::Streamed(source), budget, note: Some(note) })
        }
        _ => {
            drop(source);
            let animation = load(&args.input, &options, limits, Streams::Refuse)?.animation;
            Ok(PreparedInput { input: SearchSource::Whole(animation), budget, note: None })
        }
    }
}

/// `encode --target` (or the default quality target, `by_default`): searches the codec's
/// declared parameter space (see [`harness::search_space_target`]; with `--ladder` its rate
/// ladder alone, [`harness::search_target`]) and writes the smallest stream that meets the
/// target. Parameters given with `-p` stay fixed and are not searched.
pub(super) fn run_target(
    args: &EncodeArgs,
    target: Target,
    by_default: bool,
    limits: Limits,
    policy: &OutputPolicy,
) -> CmdResult {
    let registry = animcodec::registry();
    let auto = args.codec == "auto";
    let chosen: Option<(&dyn AnimationCodec, ParamSet)> = if auto {
        if !args.params.is_empty() {
            return Err("-p cannot be combined with -c auto: parameters belong to one codec".into());
        }
        None
    } else {
        let codec = registry.by_name(&args.codec)?;
        let params = front::params_from_text(codec, &args.params)?;
        let ladder = codec.rate_ladder(&params);
        if let Some(p) = args.params.iter().find(|p| p.split_once('=').is_some_and(|(k, _)| k.trim() == ladder.param)) {
            return Err(format!(
                "{}: '-p {p}' sets the rate ladder's parameter, which --target {target} chooses; leave it out",
                codec.name()
            )
            .into());
        }
        Some((codec, params))
    };
    // --eval's metrics: every one, with the STED options given. With --eval the search measures
    // every candidate with them, so the chosen stream's report is its evaluation (encoded and
    // decoded once); without, only the target's metrics.
    let measured = args.sted.metric_options().eval_options()?;
    let eval = if args.eval { measured } else { EvalOptions { sted: measured.sted, ..EvalOptions::default() } };
    policy.check(&args.output)?;
    animcodec::output::folder_exists(&args.output)?;

    let read_start = Instant::now();
    let registry_codecs: Vec<&dyn AnimationCodec> = registry.iter().collect();
    let searched: Vec<&dyn AnimationCodec> = match &chosen {
        Some((codec, _)) => vec![*codec],
        None => registry_codecs.clone(),
    };
    // The whole animation in memory while the search fits the memory budget; beyond it (and
    // for an input read frame by frame) the streamed search.
    let searched_params: Vec<(&dyn AnimationCodec, ParamSet)> = match &chosen {
        Some((codec, params)) => vec![(*codec, params.clone())],
        None => searched.iter().map(|c| (*c, c.default_params())).collect(),
    };
    let prepared = prepare_search_input(args, &searched_params, &eval, limits)?;
    // The files the read opened (a .gltf's buffers, …) are inputs too: refused before the work.
    policy.check(&args.output)?;
    let read_seconds = read_start.elapsed().as_secs_f64();
    // On a streamed input, a named codec's least work share (its blocks at their smallest):
    // the streams get less than a quarter of the budget when the codec needs more.
    let codec_need = match (&prepared.input, &chosen) {
        (SearchSource::Streamed(source), Some((codec, params))) => {
            harness::least_work_budget(*codec, params, source.topology().vertex_count(), source.frame_count())
        }
        _ => None,
    };
    // A film-size input's candidates are measured on a sample of its frames (`--no-sample`).
    let sample = match &prepared.input {
        SearchSource::Streamed(source) => {
            let budget = prepared.budget.expect("a streamed search has a budget");
            sample_of(args, source.as_ref(), &chosen, harness::work_share(budget, codec_need))
        }
        SearchSource::Whole(_) => None,
    };
    let streamed_input = match &prepared.input {
        SearchSource::Streamed(source) => Some(
            StreamedInput::new(
                match &sample {
                    Some(sample) => sample as &dyn InputSource,
                    None => source.as_ref(),
                },
                prepared.budget.expect("a streamed search has a budget"),
                args.feed as usize,
                &eval,
            )?
            .giving_the_codec(codec_need.unwrap_or(0)),
        ),
        SearchSource::Whole(_) => None,
    };
    let mut notes: Vec<String> = prepared.note.iter().cloned().collect();
    // On a streamed input, a codec whose encoder holds the whole input cannot stream: refused
    // (a named codec) or left out (-c auto), naming the budget.
    let mut every_codec: Vec<&dyn AnimationCodec> = registry_codecs.clone();
    if let Some(streamed) = &streamed_input {
        let (v, f) = (streamed.source().topology().vertex_count(), streamed.source().frame_count());
        let refusal = |codec: &dyn AnimationCodec, params: &ParamSet| -> Option<String> {
            codec.fit_memory(params, v, f, streamed.work_budget()).err().map(|e| {
                format!(
                    "{}: its encoder cannot stream {} within --memory {} MiB (the streamed search gives the codec \
                     {} MiB and keeps {} MiB for candidate streams): {e}",
                    codec.name(),
                    args.input,
                    streamed.budget() >> 20,
                    streamed.work_budget() >> 20,
                    (streamed.budget() - streamed.work_budget()) >> 20,
                )
            })
        };
        match &chosen {
            Some((codec, params)) => {
                if let Some(why) = refusal(*codec, params) {
                    return Err(why.into());
                }
            }
            None => every_codec.retain(|codec| match refusal(*codec, &codec.default_params()) {
                Some(why) => {
                    eprintln!("animcodec: left out of -c auto: {why}");
                    notes.push(format!("left out of -c auto: {why}"));
                    false
                }
                None => true,
            }),
        }
    }
    let sample_note = sample.as_ref().map(|sample| {
        format!(
            "{} is over {} of coordinates: the candidates are measured on {} of its {} frames ({} windows of {} \
             frames spread over it, aiming {:.0} % below the target); the chosen parameters are then encoded over \
             the whole input and that stream is measured and reported (--no-sample measures every candidate on the \
             whole)",
            args.input,
            progress::bytes_text(args.sample_above),
            sample.frame_count(),
            sample.inner().frame_count(),
            sample.windows().len(),
            sample.windows().first().map_or(0, |w| w.len()),
            (1.0 - harness::SAMPLE_TARGET_MARGIN) * 100.0,
        )
    });
    notes.extend(sample_note.iter().cloned());
    // Said once the search is sure to run (a refusal above is the one message).
    for n in prepared.note.iter().chain(&sample_note) {
        eprintln!("animcodec: {n}");
    }

    let start = Instant::now();
    let fixed: Vec<&str> = args.params.iter().filter_map(|p| p.split_once('=').map(|(k, _)| k.trim())).collect();
    // Each point is a full encode + decode + evaluation (minutes in all on real data): on a
    // terminal, the points measured of those expected, and the latest point.
    let bar = search_progress(&registry, &chosen, &fixed, target, (by_default, args.ladder), args.refine, args.json);
    let progress = |p: &harness::Point| {
        bar.inc(1);
        let knob = p.ladder_value().map_or_else(String::new, |v| format!("{}={v} ", p.ladder_param));
        bar.message(format!("last: {} {knob}→ {} at {:.3} bpvf", p.codec, target.reached_text(&p.report, 4), p.bpvf));
    };
    let mut input = match (&prepared.input, &streamed_input) {
        (_, Some(streamed)) => harness::SearchInput::Streamed(streamed),
        (SearchSource::Whole(animation), None) => harness::SearchInput::Whole(animation),
        (SearchSource::Streamed(_), None) => unreachable!("a streamed source has its streamed input"),
    };
    // The search toward `aim` (the target; on a sample, below it) on `on`.
    let search = |aim: Target, on: harness::SearchInput<'_>, sampled: bool| {
        let request = SearchRequest {
            eval,
            limits,
            refine: args.refine as usize,
            progress: &progress,
            // A sample's candidates are measured for the search alone: --eval's figures are
            // the whole stream's.
            measure_every_metric: args.eval && !sampled,
            ..SearchRequest::on(&registry, on, aim)
        };
        match &chosen {
            Some((codec, _)) if by_default && !args.ladder => {
                harness::search_default_quality(&request, *codec).map(|hit| (hit, Vec::new()))
            }
            Some((codec, params)) if args.ladder => {
                harness::search_target(&request, *codec, params).map(|hit| (hit, Vec::new()))
            }
            Some((codec, params)) => {
                harness::search_space_target(&request, *codec, params, &fixed).map(|hit| (hit, Vec::new()))
            }
            None if args.ladder => harness::search_target_auto(&request, &every_codec),
            None => harness::search_space_target_auto(&request, &every_codec),
        }
    };
    let missed = |found: &harness::Result<_>| {
        matches!(found, Err(harness::EvalError::TargetMiss(_) | harness::EvalError::NoCodecMeetsTarget { .. }))
    };
    // On a sample, aiming below the target; should the sample miss that aim (a ladder that
    // ends near the target), at the target itself (the whole is checked either way).
    let sample_input = input;
    let search_aiming = |aim: Target| match search(aim, sample_input, true) {
        found if missed(&found) && aim != target => search(target, sample_input, true),
        found => found,
    };
    let mut aim = match sample {
        Some(_) => harness::scaled_target(target, |_| harness::SAMPLE_TARGET_MARGIN),
        None => target,
    };
    let mut found = if sample.is_some() { search_aiming(aim) } else { search(aim, input, false) };
    // A sample that meets not even the target (its frames harder than the whole's: a ladder
    // whose last step the whole input passes) leaves the decision to the whole input: every
    // candidate measured on it, as without a sample.
    let whole_input = match (&prepared.input, &sample) {
        (SearchSource::Streamed(source), Some(_)) if missed(&found) => Some(
            StreamedInput::new(
                source.as_ref(),
                prepared.budget.expect("a streamed search has a budget"),
                args.feed as usize,
                &eval,
            )?
            .giving_the_codec(codec_need.unwrap_or(0)),
        ),
        _ => None,
    };
    let sampled = sample.is_some() && whole_input.is_none();
    if let Some(whole_input) = &whole_input {
        let why = format!(
            "no candidate met {target} on the sample of {} frames: every candidate is measured on the whole input \
             instead",
            input.frame_count()
        );
        eprintln!("animcodec: {why}");
        notes.push(why);
        input = harness::SearchInput::Streamed(whole_input);
        found = search(target, input, false);
    }
    // On a sample: the whole input encoded at the answer and measured, searched again aiming
    // lower by what the whole missed, up to SAMPLE_RETRIES times.
    let mut whole: Option<(harness::Point, PendingFile)> = None;
    let mut whole_encodes = 0;
    if let (true, Some(streamed)) = (sampled, &streamed_input) {
        let source = match &prepared.input {
            SearchSource::Streamed(source) => source.as_ref(),
            SearchSource::Whole(_) => unreachable!("a sample is of a streamed input"),
        };
        // The whole's figures: every --eval metric, or the target's.
        let checked = if args.eval { measured } else { target.eval_options(&measured) };
        // What the whole missed by: the error, naming the last whole encode.
        let whole_missed = |p: &harness::Point, searches: usize| -> Box<dyn std::error::Error + Send + Sync> {
            format!(
                "{}: the whole input at {} [{}] reached {}, missing the target {target}, after {searches} searches of \
                 a sample of {} frames aiming lower each time; nothing was written. Give parameters (-p) for a \
                 smaller error, or --no-sample to measure every candidate on the whole input",
                args.input,
                p.codec,
                p.params,
                target.reached_text(&p.report, 4),
                streamed.source().frame_count(),
            )
            .into()
        };
        let mut searches = 1;
        while let Ok((hit, _)) = &found {
            // A search again that lands where the whole missed before has nothing new to encode.
            if let Some((last, _)) = whole.as_ref().filter(|(p, _)| p.params == hit.point.params) {
                return Err(whole_missed(last, searches));
            }
            whole_encodes += 1;
            let (point, file) = encode_whole(
                args,
                policy,
                (&registry, &hit.point),
                source,
                (streamed.work_budget(), limits),
                &checked,
                &bar,
            )?;
            if harness::usable(&point) && target.meets(&point.report) {
                whole = Some((point, file));
                break;
            }
            if searches > SAMPLE_RETRIES {
                return Err(whole_missed(&point, searches));
            }
            let next = lower_aim(aim, &hit.point, &point);
            eprintln!(
                "animcodec: the whole input reached {}, missing the target {target} its sample met: searching the \
                 sample again aiming at {next}",
                target.reached_text(&point.report, 4)
            );
            whole = Some((point, file));
            aim = next;
            searches += 1;
            found = search_aiming(aim);
        }
    }
    bar.finish();
    // Every point measured, over every codec searched (the chosen codec's are `hit.tried`).
    let measured_points = bar.done();
    drop(bar);
    let (mut hit, others) = found?;
    let search_seconds = start.elapsed().as_secs_f64();
    // The chosen encode's warnings, as a plain encode prints them (stderr, `--json` "notes").
    let mut warnings: Vec<String> =
        hit.point.report.notes.iter().filter_map(|n| n.strip_prefix("encoder: ")).map(str::to_owned).collect();
    warnings.extend(sted_motion_note(target, &hit.point));
    for n in &warnings {
        eprintln!("animcodec: warning: {n}");
    }
    notes.extend(warnings);
    // Written under a temporary name and measured (--eval) before it replaces anything.
    let (file, evaluation) = match whole {
        // A sampled search's stream: the whole input's, written and measured already.
        Some((point, file)) => {
            hit.point = point;
            let evaluation = args.eval.then(|| (hit.point.report.clone(), hit.point.decode_seconds));
            (file, evaluation)
        }
        None => {
            if hit.stream.is_empty() {
                return Err("internal error: the search chose a stream it did not keep".into());
            }
            let mut file = policy.create(&args.output)?;
            file.write_all(&hit.stream).map_err(|e| file.error(e))?;
            // --eval: the search measured this very stream; its report is reused (the stream is
            // not decoded again unless the search skipped a metric --eval reports).
            let evaluation = if args.eval {
                file.finish()?;
                Some(match &input {
                    harness::SearchInput::Whole(animation) => {
                        front::evaluation_of(&registry, &hit, animation, &measured, limits)?
                    }
                    harness::SearchInput::Streamed(streamed) => match front::search_evaluation(&hit, &measured) {
                        Some(found) => found,
                        None => {
                            let (report, seconds) = harness::measure_stream_against(
                                &registry,
                                &hit.stream[..],
                                streamed.source(),
                                &measured,
                                limits,
                                &|_| {},
                            )?;
                            (report, seconds)
                        }
                    },
                })
            } else {
                None
            };
            (file, evaluation)
        }
    };
    let p = &hit.point;
    file.commit()?;
    // The input's shape (a sampled search's input is its sample).
    let (v, f, triangles, frame_rate) = match &prepared.input {
        SearchSource::Whole(a) => (a.vertex_count(), a.frame_count(), a.topology().triangle_count(), a.frame_rate()),
        SearchSource::Streamed(source) => (
            source.topology().vertex_count(),
            source.frame_count(),
            source.topology().triangle_count(),
            source.frame_rate(),
        ),
    };
    if args.json {
        return emit_document(&TargetEncodeDocument {
            summary: TargetSummary::new(target, &hit, &others),
            input: &args.input,
            output: args.output.display().to_string(),
            default_target: by_default,
            search: if args.ladder { "ladder" } else { "space" },
            notes,
            search_input: match (sampled, &streamed_input) {
                (true, _) => "sampled",
                (false, Some(_)) => "streamed",
                (false, None) => "whole",
            },
            sample_frames: sample.as_ref().filter(|_| sampled).map(|s| s.frame_count()),
            whole_encodes: sampled.then_some(whole_encodes),
            memory_budget: prepared.budget,
            memory_budget_default: args.memory.is_none() && prepared.budget.is_some(),
            ratio: raw_bytes(v, f) as f64 / p.bytes as f64,
            frames: f,
            vertices: v,
            triangles,
            frame_rate,
            read_seconds,
            search_seconds,
            encode_seconds: p.encode_seconds,
            evaluation: evaluation.as_ref().map(|(r, s)| EvaluationFields::new(r, *s)),
        });
    }
    let mut out = format!(
        "{input}: {f} frames × {v} vertices ({read})\n\
         target {target}{default}: {codec} [{params}] reaches {reached} → {output}\n\
         {parts}{bytes} bytes, {rate:.3} bits/vertex/frame; searched {n} in {search_seconds:.2} s{fallback}\n",
        input = args.input,
        read = if let Some(sample) = sample.as_ref().filter(|_| sampled) {
            format!(
                "streamed: candidates measured on a sample of {} frames, the whole encoded and measured {}",
                sample.frame_count(),
                match whole_encodes {
                    1 => "once".to_owned(),
                    n => format!("{n} times"),
                }
            )
        } else if streamed_input.is_some() {
            "streamed: read twice per candidate".to_owned()
        } else {
            format!("read in {read_seconds:.2} s")
        },
        default = if by_default { " (the default quality; -p or --target for other choices)" } else { "" },
        codec = p.codec,
        params = p.params,
        reached = target.reached_text(&p.report, 6),
        output = args.output.display(),
        bytes = p.bytes,
        rate = p.bpvf,
        n = match measured_points as usize {
            n if n > hit.tried.len() => format!("{n} points ({} for {})", hit.tried.len(), p.codec),
            _ => format!("{} points", hit.tried.len()),
        },
        // A KG bound holds for every part; say which figure it was.
        parts = match (&p.report.worst_part, target.bound(TargetMetric::Kg)) {
            (Some(w), Some(_)) if p.report.parts > 1 => format!(
                "kg is the larger of the whole animation's ({}) and the worst of its {} parts' (part {}, {} vertices: {})\n",
                p.report.kg.map_or_else(|| "n/a".to_string(), |x| format!("{x:.6}")),
                p.report.parts,
                w.part,
                w.vertices,
                w.kg.map_or_else(|| "n/a".to_string(), |x| format!("{x:.6}")),
            ),
            _ => String::new(),
        },
        fallback = if hit.linear_fallback { " (errors not monotone along the ladder: linear scan used)" } else { "" },
    );
    for r in &hit.rejected {
        out.push_str(&format!("  rejected candidate: {r}\n"));
    }
    if let Some((r, seconds)) = &evaluation {
        let num = |x: Option<f64>| x.map_or_else(|| "n/a".to_string(), |x| format!("{x:.4e}"));
        out.push_str(&format!(
            "decoded vs input: KG {} %, STED {}, Hausdorff {}, RMSE {:.4e}, max error {:.4e} (measured in {seconds:.2} s)\n",
            num(r.kg),
            num(r.sted),
            num(r.hausdorff),
            r.rmse,
            r.max_error,
        ));
        out.push_str(&worst_part_line(r));
    }
    for o in &others {
        out.push_str(&format!(
            "  also meets it: {} [{}] {} bytes, {:.3} bpvf\n",
            o.point.codec, o.point.params, o.point.bytes, o.point.bpvf
        ));
    }
    emit(&out)
}

/// How many times a sampled search runs again when the whole input misses the target its sample
/// met (each time aiming lower by what the whole missed, [`lower_aim`]).
const SAMPLE_RETRIES: usize = 2;

/// The sample a search on `source` measures its candidates on ([`harness::SampledSource`]):
/// `None` with `--no-sample`, at or below `--sample-above` ([`front::SAMPLED_SEARCH_MIN_RAW`] by
/// default), or when a sample
/// would hold more than half the frames. Its windows are whole independent temporal blocks of
/// the named codec at its parameters fitted to the `work` share of the budget
/// ([`AnimationCodec::independent_blocks`]; hosvd decomposing the whole sequence has one block,
/// so it is not sampled); for a codec whose blocks depend on earlier ones (pca-aoi's AOI
/// modes), its `block` parameter's (the windows then start where the whole's blocks do); else
/// [`harness::UNALIGNED_SAMPLE_BLOCK`] frames.
fn sample_of<'a>(
    args: &EncodeArgs,
    source: &'a dyn InputSource,
    chosen: &Option<(&dyn AnimationCodec, ParamSet)>,
    work: u64,
) -> Option<harness::SampledSource<'a>> {
    let (v, f) = (source.topology().vertex_count(), source.frame_count());
    let raw = (v as u64).saturating_mul(f as u64).saturating_mul(12);
    if args.no_sample || raw <= args.sample_above {
        return None;
    }
    let block = match chosen {
        Some((codec, params)) => {
            let fitted = codec.fit_memory(params, v, f, work).ok()?;
            let declared = || match fitted.get("block") {
                Some(animcodec::core::ParamValue::Int(b)) if *b > 0 => usize::try_from(*b).ok(),
                _ => None,
            };
            codec.independent_blocks(&fitted, f).ok().or_else(declared).unwrap_or(harness::UNALIGNED_SAMPLE_BLOCK)
        }
        None => harness::UNALIGNED_SAMPLE_BLOCK,
    };
    harness::SampledSource::new(source, block)
}

/// The whole input encoded at a sampled search's answer (`point`'s parameters, fitted to the
/// whole input already) into a new pending output, then measured with `eval` against another
/// read of it, the decode and the metrics within the work budget: the point as the whole made
/// it (bytes, rate, report, seconds) and its file, complete, not committed. `status` shows the
/// frames done.
fn encode_whole(
    args: &EncodeArgs,
    policy: &OutputPolicy,
    (registry, point): (&animcodec::core::CodecRegistry, &harness::Point),
    source: &dyn InputSource,
    (work_budget, limits): (u64, Limits),
    eval: &EvalOptions,
    status: &Progress,
) -> CmdResult<(harness::Point, PendingFile)> {
    let codec = registry.by_name(point.codec)?;
    let (v, f) = (source.topology().vertex_count(), source.frame_count());
    let start = Instant::now();
    let encoding = |n: usize| status.message(format!("the whole input at {}: encoded {n}/{f} frames", point.params));
    let (mut file, notes) = harness::encode_source(
        codec,
        &point.params,
        source,
        args.feed as usize,
        policy.create(&args.output)?,
        &encoding,
    )?;
    let encode_seconds = start.elapsed().as_secs_f64();
    let path = file.finish()?.to_path_buf();
    let bytes = std::fs::metadata(&path).map_err(|e| file.error(e))?.len();
    let limits = harness::measurement_limits(codec.name(), work_budget, limits, source.topology(), eval)?;
    let measuring = |n: usize| status.message(format!("the whole stream: measured {n}/{f} frames"));
    let (mut report, decode_seconds) =
        harness::measure_stream_against(registry, front::open_stream(&path)?, source, eval, limits, &measuring)?;
    report.notes.extend(notes.into_iter().map(|n| format!("encoder: {n}")));
    let point = harness::Point {
        bytes,
        bpvf: animcodec::metrics::bpvf(bytes, v, f)?,
        report,
        encode_seconds,
        decode_seconds,
        ..point.clone()
    };
    Ok((point, file))
}

/// The next aim of a sampled search whose answer missed the target on the whole input: each
/// bound of `aim` times the sample's value over the whole's (`sample` and `whole`: the same
/// parameters measured on each; never raised), and the margin once more.
fn lower_aim(aim: Target, sample: &harness::Point, whole: &harness::Point) -> Target {
    harness::scaled_target(aim, |metric| {
        let ratio = match (metric.value(&sample.report), metric.value(&whole.report)) {
            (Some(s), Some(w)) if w > 0.0 && s.is_finite() && w.is_finite() => (s / w).min(1.0),
            _ => 1.0,
        };
        ratio * harness::SAMPLE_TARGET_MARGIN
    })
}

/// The progress display of a target search: the points expected of the search `encode` runs
/// (`by_default`: the default quality; `ladder`: `--ladder`), over every codec for `-c auto`
/// (`chosen` is `None`).
fn search_progress(
    registry: &animcodec::core::CodecRegistry,
    chosen: &Option<(&dyn AnimationCodec, ParamSet)>,
    fixed: &[&str],
    target: Target,
    (by_default, ladder): (bool, bool),
    refine: u32,
    json: bool,
) -> Progress {
    let search = match (by_default, ladder) {
        (_, true) => progress::Search::Ladder,
        (true, false) if chosen.is_some() => progress::Search::DefaultQuality,
        _ => progress::Search::Space,
    };
    let expect = |codec: &dyn AnimationCodec, base: &ParamSet, fixed: &[&str]| {
        progress::expected_search_points(codec, base, fixed, target, search, refine as usize)
    };
    let expected = match chosen {
        Some((codec, params)) => expect(*codec, params, fixed),
        None => registry.iter().map(|c| expect(c, &c.default_params(), &[])).sum(),
    };
    let bar = Progress::estimate("encode", expected, "points", json);
    bar.message(format!("searching for {target}"));
    bar
}

/// KG (%) above which a stream chosen for a STED target gets a note: it keeps the shape but
/// visibly not the motion.
const STED_MOTION_NOTE_KG: f64 = 5.0;

/// The note for a STED target met by a stream that does not follow the motion: STED (the
/// metric author's tool) weighs its temporal part by about 1e-4, so a shape moved rigidly — or
/// even frame 0 repeated — can meet it (samba at STED ≤ 0.1 is met by hosvd's
/// `(v, f) = (3, 1)` model at KG 19).
fn sted_motion_note(target: Target, point: &harness::Point) -> Option<String> {
    let kg = point.report.kg?;
    let sted = target.bound(TargetMetric::Sted).filter(|_| target.bound(TargetMetric::Kg).is_none())?;
    (kg > STED_MOTION_NOTE_KG).then(|| {
        format!(
            "the stream meets STED <= {} at KG {kg:.1} %: STED sees edge lengths, hardly motion, so this stream \
             keeps the shape but not all of the motion; use --target kg=... (or both checks, --eval) when the motion \
             matters",
            sted
        )
    })
}
