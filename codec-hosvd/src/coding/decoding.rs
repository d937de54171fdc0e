//! The decoder's side of the toolkit coding: the operator's components read from the
//! arithmetic-coded bytes in the encoder's order and reconstructed with the same predictors.

use codec_core::toolkit::adaptive::AdaptiveDecoder;
use codec_core::toolkit::order::CausalGraph;
use codec_core::toolkit::predict::{self, Predictor};
use codec_core::toolkit::regress::{Fit, Neighbourhoods, Regression, MAX_REGRESSORS};
use codec_core::{Error, Result};

use super::smoothing::{Smoother, SMOOTHING_ITERATIONS};
use super::{current_fit, relstep, ColumnMode, CLASSES_PER_GROUP, GROUPS};
use crate::NAME;

/// The decoder's side of [`code`](super::code): `(U1, U3, core)` from the steps and the arithmetic-coded
/// bytes. `steps` were checked finite and non-negative by the caller.
#[allow(clippy::too_many_arguments)]
pub fn decode(
    bytes: &[u8],
    mesh: &CausalGraph,
    mesh_predictor: Predictor,
    time_predictor: Predictor,
    frames: usize,
    v: usize,
    f: usize,
    steps: &[f32],
    column_modes: Option<&[u8]>,
    guarded: bool,
    step_scales: Option<StepScales<'_>>,
) -> Result<(Vec<f64>, Vec<f64>, Vec<f64>)> {
    let k = mesh.len();
    if steps.len() != 2 * v + f {
        return Err(Error::malformed(NAME, "steps", format!("{} steps, expected {}", steps.len(), 2 * v + f)));
    }
    let modes: Vec<ColumnMode> = match column_modes {
        Some(bytes) => {
            if bytes.len() != v {
                return Err(Error::malformed(NAME, "column modes", format!("{} bytes, expected {v}", bytes.len())));
            }
            let mode = |(i, &b): (usize, &u8)| {
                ColumnMode::from_byte(b, i).ok_or_else(|| {
                    Error::malformed(NAME, "column modes", format!("column {i}: mode {b} (0..=2; 1 not for column 0)"))
                })
            };
            bytes.iter().enumerate().map(mode).collect::<Result<_>>()?
        }
        None => vec![ColumnMode::Mesh; v],
    };
    let time = CausalGraph::chain(frames, time_predictor == Predictor::Parallelogram);
    let core_chain = CausalGraph::chain(3 * f, false);
    let mut dec = AdaptiveDecoder::new(bytes, GROUPS * CLASSES_PER_GROUP, NAME, "codes")?;
    let mut codes = Vec::new();
    let mut recon = Vec::new();
    let mut u1 = vec![0.0; k * v];
    // Regression (version 4): the caller checked the neighbourhoods' size against its limits.
    let leads = if modes.contains(&ColumnMode::Regression) { v.saturating_sub(1).min(MAX_REGRESSORS) } else { 0 };
    let hoods = (leads > 0).then(|| Neighbourhoods::new(mesh));
    let mut decoded_leads: Vec<Vec<f64>> = Vec::with_capacity(leads);
    let mut fit: Option<(usize, Fit)> = None;
    let mut scales: Option<Vec<f64>> = None;
    for i in 0..v {
        let class = i.min(CLASSES_PER_GROUP - 1);
        if let Some(s) = step_scales.as_ref().filter(|_| i == relstep::SCALED_FROM) {
            scales = Some(s.scales(mesh, &u1, v)?);
        }
        let w = scales.as_deref();
        let r = match (&hoods, modes[i]) {
            (Some(hoods), ColumnMode::Regression) => {
                let n = i.min(leads);
                let refs: Vec<&[f64]> = decoded_leads[..n].iter().map(|x| x.as_slice()).collect();
                let lead_steps: Vec<f64> = steps[..n].iter().map(|&s| s as f64).collect();
                let fit = current_fit(&mut fit, n, hoods, &refs, &lead_steps, guarded);
                let reg = Regression { graph: mesh, fallback: mesh_predictor, hoods, fit };
                component(&mut dec, &mut codes, &mut recon, mesh, mesh_predictor, Some(&reg), class, (steps[i], w))?
            }
            (_, ColumnMode::Parallelogram) => {
                let pred = Predictor::Parallelogram;
                component(&mut dec, &mut codes, &mut recon, mesh, pred, None, class, (steps[i], w))?
            }
            _ => component(&mut dec, &mut codes, &mut recon, mesh, mesh_predictor, None, class, (steps[i], w))?,
        };
        for (p, &x) in mesh.order().iter().enumerate() {
            u1[x as usize * v + i] = r[p];
        }
        if i < leads {
            decoded_leads.push(r.to_vec());
        }
    }
    let mut u3 = vec![0.0; frames * f];
    for l in 0..f {
        let r = component(
            &mut dec,
            &mut codes,
            &mut recon,
            &time,
            time_predictor,
            None,
            CLASSES_PER_GROUP + l.min(CLASSES_PER_GROUP - 1),
            (steps[v + l], None),
        )?;
        for (t, &x) in r.iter().enumerate() {
            u3[t * f + l] = x;
        }
    }
    let mut core = vec![0.0; 3 * v * f];
    for i in 0..v {
        let r = component(
            &mut dec,
            &mut codes,
            &mut recon,
            &core_chain,
            Predictor::Zero,
            None,
            2 * CLASSES_PER_GROUP + i.min(CLASSES_PER_GROUP - 1),
            (steps[v + f + i], None),
        )?;
        core[i * 3 * f..(i + 1) * 3 * f].copy_from_slice(r);
    }
    // Every coded word was read (a header claiming fewer values than were coded is
    // an error, as is one claiming more: the decoder then runs past its data).
    dec.finish()?;
    Ok((u1, u3, core))
}

/// What the decoder needs for the `U1` columns' per-vertex step scales (stream version 7,
/// [`relstep`]): the strength byte, the stored gains of the leading columns and the smoothing
/// levels (the scales come from the *smoothed* leads).
pub struct StepScales<'a> {
    /// Strength byte, `1..=4` (checked by the caller).
    pub strength: u8,
    /// Gains of the leading columns (finite, checked by the caller).
    pub gains: [f32; relstep::LEADS],
    /// Smoothing level per `U1` column (`None` without `denoise`).
    pub levels: Option<&'a [u8]>,
}

impl StepScales<'_> {
    /// The scales from the decoded leading columns of `u1` (`K × v`, vertex order), each
    /// smoothed at its level as the caller will smooth `u1` afterwards.
    fn scales(&self, mesh: &CausalGraph, u1: &[f64], v: usize) -> Result<Vec<f64>> {
        let smoother = self.levels.map(|_| Smoother::new(mesh));
        let mut tmp = Vec::new();
        let mut leads = Vec::with_capacity(relstep::LEADS);
        for i in 0..relstep::LEADS.min(v) {
            let mut col: Vec<f64> = mesh.order().iter().map(|&x| u1[x as usize * v + i]).collect();
            if let (Some(sm), Some(levels)) = (&smoother, self.levels) {
                let level = levels.get(i).copied().unwrap_or(0);
                let iterations = *SMOOTHING_ITERATIONS.get(level as usize).ok_or_else(|| {
                    Error::malformed(NAME, "smoothing", format!("level {level} of column {i}, at most 7"))
                })?;
                sm.smooth(&mut col, iterations as usize, &mut tmp);
            }
            leads.push(col);
        }
        let gains: Vec<f64> = self.gains.iter().map(|&g| g as f64).collect();
        Ok(relstep::vertex_scales(mesh, &leads, &gains, self.strength))
    }
}

/// Decodes one component's codes and reconstructs it (position order) into `recon`.
#[allow(clippy::too_many_arguments)]
fn component<'r>(
    dec: &mut AdaptiveDecoder,
    codes: &mut Vec<i32>,
    recon: &'r mut Vec<f64>,
    graph: &CausalGraph,
    predictor: Predictor,
    regression: Option<&Regression<'_>>,
    class: usize,
    (step, scales): (f32, Option<&[f64]>),
) -> Result<&'r [f64]> {
    recon.clear();
    if step == 0.0 {
        recon.resize(graph.len(), 0.0);
        return Ok(recon);
    }
    codes.clear();
    codes.resize(graph.len(), 0);
    for p in 0..graph.len() {
        let bucket = predict::neighbour_bucket(graph, codes, p);
        codes[p] = dec.decode(class, bucket)?;
    }
    match regression {
        Some(reg) => reg.dequantize_scaled(codes, step as f64, scales, recon),
        None => predict::dequantize_scaled(graph, predictor, codes, step as f64, scales, recon),
    }
    if recon.iter().any(|x| !x.is_finite()) {
        return Err(Error::malformed(NAME, "codes", "a decoded value is not finite"));
    }
    Ok(recon)
}
