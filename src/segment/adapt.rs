//! The model's slow adaptation (see the module docs of [`super`]): a running mean on a
//! rotating band of rows, away from the person.

use super::{keep_out_box, BackgroundModel, PixelBox, ADAPT_ROW_STRIDE, COARSE, COLOR_Q};
use image::RgbImage;

impl BackgroundModel {
    /// Running-mean update of a rotating band of rows, outside the person's box.
    pub(super) fn adapt(&mut self, frame: &RgbImage, person: Option<PixelBox>) {
        let rate = self.opts.adapt_rate;
        if rate <= 0.0 {
            return;
        }
        let w = self.width as usize;
        let raw = frame.as_raw();
        let phase = self.frames % ADAPT_ROW_STRIDE;
        let keep_out = person.map(keep_out_box);
        let cw = w.div_ceil(COARSE as usize);
        let mut y = phase as usize;
        while y < self.height as usize {
            // The row's spans outside the person's box.
            let (a, b) = match keep_out {
                Some((x0, y0, x1, y1)) if y >= y0 && y < y1 => ((0, x0.min(w)), (x1.min(w), w)),
                _ => ((0, w), (w, w)),
            };
            let coarse_row = y
                .is_multiple_of(COARSE as usize)
                .then(|| (y / COARSE as usize) * cw);
            for x in (a.0..a.1).chain(b.0..b.1) {
                let i = y * w + x;
                let p = [raw[3 * i], raw[3 * i + 1], raw[3 * i + 2]];
                if self.is_foreground(i, p) {
                    continue; // someone else, or a change too large to learn silently
                }
                // The raw colour: the model follows a lasting drift of the light, so the
                // gain only has the frame's flicker about it to explain. The noise radius
                // and the zone stay.
                let e = self.px[i].color();
                let m = [0, 1, 2].map(|c| (e[c] + rate * (p[c] as f32 - e[c])).clamp(1.0, 255.0));
                self.px[i].e_q8 = m.map(|v| (v * COLOR_Q + 0.5) as u16);
                if let Some(row) = coarse_row.filter(|_| x.is_multiple_of(COARSE as usize)) {
                    let k = row + x / COARSE as usize;
                    if k < self.coarse_model.er.len() {
                        self.coarse_model.set_colour(k, m);
                    }
                }
            }
            y += ADAPT_ROW_STRIDE as usize;
        }
    }
}
