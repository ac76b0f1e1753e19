//! The first fit of a subject (method.md sections 2-4): the library body nearest the
//! silhouettes' shape descriptor, refined, scaled and placed on the subject, posed like
//! it, and the deformer set up on its controls. Later frames only refit its controls.

use super::*;
use crate::camera::Camera;

impl Fitter {
    /// Chooses, places and poses the subject's candidate body and sets up its deformer
    /// (`fitted`: a descriptor from an earlier pass's fitted sections, else the
    /// silhouettes' own).
    pub(super) fn first_fit(
        &mut self,
        calib: &StationCalibration,
        front: MaskRef<'_>,
        side: Option<MaskRef<'_>>,
        obs: &Observation,
        fitted: Option<&shape::ShapeDescriptor>,
    ) -> Result<(), FitError> {
        let f = (&calib.front, front);
        let sd = side.map(|s| (&calib.side, s));
        let observed = match fitted {
            Some(d) => d.clone(),
            None => shape::observed_descriptor(f, sd, obs.stature_m, obs.torso_point),
        };
        let params = self.choose_candidate(&observed, fitted.is_some())?;
        // 3. Body, scaled to the stature and placed on the subject.
        let mut body = self.library.body(&params);
        let (k, seen) = self.place_candidate(&mut body, f, sd, obs);
        // Vertical proportions: the crotch where the front view sees it (the library's
        // proportions are a prior; the gap between the legs is measured).
        self.align_crotch(&mut body, calib, front, seen, obs.stature_m);
        // 4. Pose synchronisation.
        pose::synchronise(&mut body, &self.template_labels, &self.pose_joints, k, obs);
        // The candidate's own levels for the waist's section prior, taken facing the
        // front camera (the hip's furthest-back point moves on a turned body).
        let waist_band = if self.opts.waist_prior && self.opts.dense_sections {
            crate::measure::measure(&body).ok().and_then(|m| {
                let l = &m.levels;
                section_prior::WaistBand::new(l.hip_m, l.waist_m, l.chest_m)
            })
        } else {
            None
        };
        // The turn on the mark the side view's toes show.
        let turned = match sd {
            Some((cam, mask)) if self.opts.turn_from_toes => {
                self.turn_to_toes(&mut body, cam, mask, seen)
            }
            _ => None,
        };
        // 5. Controls and deformer on the posed candidate.
        let mut subject = self.prepare_subject(body, params, calib, waist_band)?;
        if let Some(t) = turned {
            // The sections are mapped in the body's own axes: its rims and rest
            // positions turned back (the waist's prior, the legs' shared depth map).
            if let Some(plan) = subject.plan.as_mut() {
                plan.turn_rims(seen, -t.yaw);
            }
            subject.rest_square = subject.rest.positions.clone();
            turn::turn(&mut subject.rest_square, seen, -t.yaw);
        }
        subject.turn = turned.map(|t| (t, seen));
        self.subject = Some(subject);
        Ok(())
    }

    /// Steps 1-2: the library body whose descriptor is nearest `observed`, its macro
    /// parameters refined on it by Gauss-Newton when that pays (`refit_pass`: the
    /// descriptor comes from fitted sections, not the raw silhouettes).
    fn choose_candidate(
        &self,
        observed: &shape::ShapeDescriptor,
        refit_pass: bool,
    ) -> Result<ShapeParams, FitError> {
        if observed
            .torso_width
            .iter()
            .filter(|w| w.is_finite())
            .count()
            < shape::TORSO_LEVELS.len() / 2
        {
            return Err(FitError::NoTorso);
        }
        let best = self
            .library_descriptors
            .iter()
            .enumerate()
            .min_by(|a, b| a.1.distance2(observed).total_cmp(&b.1.distance2(observed)))
            .map(|(i, _)| i)
            .ok_or(FitError::NoTorso)?;
        let mut params = self.library_params[best].clone();
        // The raw silhouettes' descriptor mixes in arms and legs: refining the macro
        // parameters against it is wasted effort when a later pass refines against the
        // fitted sections.
        if self.opts.refine_shape && (refit_pass || self.opts.candidate_passes <= 1) {
            params = shape_refine(
                &self.library,
                &self.edges,
                &self.template_labels,
                params,
                observed,
                self.opts.shape_iterations,
                if self.opts.refine_cup {
                    &ALL_PARAMS
                } else {
                    &MACRO_PARAMS
                },
            )
            .0;
        }
        Ok(params)
    }

    /// Step 3: scales `body` to the stature and moves it so that its torso's centre at
    /// the reference height lands on the silhouettes' section centre there (x from the
    /// front view, z from the side). Returns the scale and that centre.
    fn place_candidate(
        &self,
        body: &mut TriMesh,
        f: (&Camera, MaskRef<'_>),
        sd: Option<(&Camera, MaskRef<'_>)>,
        obs: &Observation,
    ) -> (f64, DVec3) {
        let stature = body.bounds().map(|b| b.size().y).unwrap_or(1.0).max(1e-3);
        let k = obs.stature_m / stature;
        let mut seen =
            shape::section_centre(f, sd, PLACEMENT_LEVEL * obs.stature_m, obs.torso_point)
                .map(|c| c.0)
                .unwrap_or(obs.torso_point);
        // Two views cannot tell a hand held in front of the belly from the belly: where the
        // side silhouette merges them, the section's centre moves forward by half the
        // hand's reach. The landmarks' torso point (the side contour's axis, arm parts
        // left out) bounds it: the trunk's centre lies within a posture's lean of it.
        let lean = PLACEMENT_MAX_LEAN * obs.stature_m;
        seen.z = seen
            .z
            .clamp(obs.torso_point.z - lean, obs.torso_point.z + lean);
        let own = shape::torso_centre(
            &body.positions,
            &self.edges,
            &self.template_labels,
            PLACEMENT_LEVEL * stature,
        )
        .unwrap_or(DVec3::ZERO);
        if debug_enabled() {
            eprintln!(
                "placement: seen {seen:?} own {own:?} k {k:.4} torso_point {:?}",
                obs.torso_point
            );
        }
        body.map_positions(|p| {
            DVec3::new(
                (p.x - own.x) * k + seen.x,
                p.y * k,
                (p.z - own.z) * k + seen.z,
            )
        });
        (k, seen)
    }

    /// Turns the posed candidate `body` about the vertical through `about` by the turn the
    /// side view's toes show ([`turn`]); the estimate, or None (left unturned).
    fn turn_to_toes(
        &self,
        body: &mut TriMesh,
        cam: &Camera,
        mask: MaskRef<'_>,
        about: DVec3,
    ) -> Option<turn::TurnEstimate> {
        let foot = |g: &[u32]| -> Vec<DVec3> {
            g.iter()
                .filter_map(|&i| body.positions.get(i as usize).copied())
                .collect()
        };
        let [l, r] = [foot(&self.feet[0]), foot(&self.feet[1])];
        let t = turn::turn_from_toes(cam, mask, [&l, &r], about);
        if debug_enabled() {
            eprintln!("turn from the toes: {t:?}");
        }
        let t = t.ok()?;
        turn::turn(&mut body.positions, about, t.yaw);
        Some(t)
    }

    /// Step 5: the posed candidate's controls (slice extremes or rims, the rigid parts
    /// pinned, the sections' dense vertices) and its deformer, as the subject's state
    /// (`waist_band`: the levels of the waist's section prior, None: the candidate's
    /// own shape there).
    fn prepare_subject(
        &self,
        body: TriMesh,
        params: ShapeParams,
        calib: &StationCalibration,
        waist_band: Option<section_prior::WaistBand>,
    ) -> Result<SubjectState, FitError> {
        let step = body.mean_edge_length();
        let mut excluded = vec![false; body.vertex_count()];
        for g in &self.rigid {
            for &v in g {
                excluded[v as usize] = true;
            }
        }
        let controls = correspond::select_controls(
            &body,
            &self.template_labels,
            &excluded,
            step,
            self.opts.variant,
            &calib.front,
            &calib.side,
        );
        let pinned: Vec<u32> = (0..body.vertex_count() as u32)
            .filter(|&v| excluded[v as usize])
            .collect();
        let mut indices: Vec<u32> = controls.controls.iter().map(|c| c.vertex).collect();
        let (plan, dense) = if self.opts.dense_sections {
            let mut plan = sections::SectionPlan::new(&controls);
            plan.set_rims(
                &body.positions,
                &self.edges,
                &self.template_labels,
                &controls,
                [&calib.front, &calib.side],
            );
            // The candidate's own levels: the mapped targets keep its heights.
            plan.set_waist_band(waist_band);
            let mut taken = vec![false; body.vertex_count()];
            for &v in indices.iter().chain(&pinned) {
                taken[v as usize] = true;
            }
            let dense: Vec<u32> = plan
                .vertices
                .iter()
                .copied()
                .filter(|&v| !std::mem::replace(&mut taken[v as usize], true))
                .collect();
            (Some(plan), dense)
        } else {
            (None, Vec::new())
        };
        indices.extend_from_slice(&dense);
        indices.extend_from_slice(&pinned);
        let dopts = DecodeOptions {
            max_iterations: DECODE_ITERATIONS_PER_SOLVE,
            ..DecodeOptions::default()
        };
        let mut deformer = FitDeformer::new(self.opts.deformer, &body, self.opts.decoder, dopts)
            .map_err(|e| FitError::Deform(e.to_string()))?;
        deformer
            .set_controls(&indices)
            .map_err(|e| FitError::Deform(e.to_string()))?;
        Ok(SubjectState {
            plan,
            dense,
            pinned,
            params,
            controls,
            deformer,
            positions: body.positions.clone(),
            rest: body,
            rest_square: Vec::new(),
            turn: None,
        })
    }
}
