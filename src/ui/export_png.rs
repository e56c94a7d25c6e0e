//! PNG export of the Trends panel's plots and of a sim-vs-real analysis, drawn by the very
//! widgets the screen shows.
//!
//! A private egui context runs the panel's drawing code ([`super::panels::trends::plots_ui`],
//! [`super::panels::model_lab::result_ui`]) on the view model, epaint tessellates the result
//! into triangles, and a small software rasteriser here fills them into an RGBA image (egui's
//! feathered edges make that anti-aliased). No window, GPU or second plotting library is involved, so the export works
//! the same on a headless test machine and runs on a job thread, never on the UI thread.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use eframe::egui;
use egui::epaint::{ClippedPrimitive, ColorImage, ImageDelta, Primitive, TextureId};

use super::jobs::{JobContext, JobStop};
use super::vm::discrepancy::DiscrepancyResultView;
use super::vm::trends::TrendsView;

/// Why a PNG could not be made.
#[derive(Debug, thiserror::Error)]
pub enum PngError {
    /// Nothing is drawn.
    #[error("nothing to export: choose at least one channel with data in the window")]
    Empty,
    /// The image could not be encoded or written.
    #[error("{path}: {message}")]
    Write {
        /// The file.
        path: String,
        /// What went wrong.
        message: String,
    },
}

/// What a PNG shows.
#[derive(Debug, Clone)]
pub enum PngFigure {
    /// The Trends panel's plots, at a given size in pixels.
    Trends {
        /// The plots as shown.
        view: TrendsView,
        /// Image size, pixels.
        size: [u32; 2],
    },
    /// A sim-vs-real analysis as the Model lab shows it, `width` pixels wide and as tall as
    /// the report ([`render_discrepancy`]).
    Discrepancy {
        /// The analysis as shown.
        view: Box<DiscrepancyResultView>,
        /// Image width, pixels.
        width: u32,
    },
}

/// What to export.
#[derive(Debug, Clone)]
pub struct PngRequest {
    /// What the image shows.
    pub figure: PngFigure,
    /// Dark or light theme (as on screen).
    pub dark: bool,
    /// Where to write.
    pub path: PathBuf,
}

/// A written export.
#[derive(Debug, Clone, PartialEq)]
pub struct PngOutcome {
    /// The file.
    pub path: PathBuf,
    /// Image size, pixels.
    pub size: [u32; 2],
}

/// Draws `view`'s plots into an RGBA image of `size` pixels.
pub fn render_trends(view: &TrendsView, dark: bool, size: [u32; 2]) -> Result<Canvas, PngError> {
    if view.plots.is_empty() && view.straightness.is_empty() {
        return Err(PngError::Empty);
    }
    Ok(render_ui(dark, size[0], Height::Fixed(size[1]), |ui| {
        ui.heading(format!(
            "servosight trends — machine time {:.1} s to {:.1} s",
            view.t0, view.t1
        ));
        ui.label(&view.resolution);
        super::panels::trends::plots_ui(ui, view, true, None);
    }))
}

/// Draws a sim-vs-real analysis as the Model lab shows it (verdict, fit before and after,
/// findings, the residual with its mismatch regions, real vs sim vs corrected) into an image
/// `width` pixels wide and as tall as its content (at most [`MAX_HEIGHT`]): `servosight
/// discrepancy --plot`.
pub fn render_discrepancy(view: &DiscrepancyResultView, dark: bool, width: u32) -> Canvas {
    render_ui(dark, width, Height::Content { max: MAX_HEIGHT }, |ui| {
        ui.heading(format!("servosight discrepancy — {}", view.target));
        super::panels::model_lab::result_ui(ui, view);
    })
}

/// The tallest image [`render_discrepancy`] makes, pixels.
pub const MAX_HEIGHT: u32 = 4000;

fn screen_input(size: [u32; 2]) -> egui::RawInput {
    let screen =
        egui::Rect::from_min_size(egui::Pos2::ZERO, egui::vec2(size[0] as f32, size[1] as f32));
    egui::RawInput {
        screen_rect: Some(screen),
        ..Default::default()
    }
}

fn themed_context(dark: bool) -> egui::Context {
    let ctx = egui::Context::default();
    super::install_fonts(&ctx);
    ctx.set_theme(if dark {
        egui::Theme::Dark
    } else {
        egui::Theme::Light
    });
    ctx
}

/// How tall an image is.
#[derive(Debug, Clone, Copy)]
enum Height {
    /// This many pixels.
    Fixed(u32),
    /// As tall as what is drawn, at most `max` pixels.
    Content {
        /// The tallest image.
        max: u32,
    },
}

/// Runs `draw` in a central panel of a private egui context and rasterises what it paints.
fn render_ui(
    dark: bool,
    width: u32,
    height: Height,
    mut draw: impl FnMut(&mut egui::Ui),
) -> Canvas {
    let ctx = themed_context(dark);
    let mut textures: HashMap<TextureId, ColorImage> = HashMap::new();
    let page = match height {
        Height::Fixed(h) | Height::Content { max: h } => h,
    };
    let (mut full, bottom) = run_twice(&ctx, [width, page], &mut draw, &mut textures);
    let mut size = [width, page];
    if let Height::Content { max } = height {
        // Laid out on a page taller than the content first, to find where it ends.
        let fitted = (bottom.ceil() as u32 + 12).clamp(64, max);
        if fitted != page {
            size = [width, fitted];
            full = run_twice(&ctx, size, &mut draw, &mut textures).0;
        }
    }
    let ppp = full.pixels_per_point;
    let primitives = ctx.tessellate(full.shapes, ppp);
    let mut canvas = Canvas::new(size[0], size[1]);
    for primitive in &primitives {
        canvas.fill_primitive(primitive, ppp, &textures);
    }
    canvas
}

/// Two passes of `draw` on a page of `size` pixels: the first lays out (plots size their axes
/// from the text they measured), the second draws the settled layout. The font textures both
/// ask for go into `textures`. Returns the second pass's output and where its content ends,
/// points from the top (where the next widget would go: the panel's own rectangle fills the
/// page whatever its content).
fn run_twice(
    ctx: &egui::Context,
    size: [u32; 2],
    draw: &mut impl FnMut(&mut egui::Ui),
    textures: &mut HashMap<TextureId, ColorImage>,
) -> (egui::FullOutput, f32) {
    let mut bottom = 0.0;
    let mut pass = || {
        let mut full = ctx.run_ui(screen_input(size), |ui| {
            egui::CentralPanel::default().show(ui, |ui| {
                draw(ui);
                bottom = ui.cursor().min.y;
            });
        });
        for (id, deltas) in &full.textures_delta.set {
            for delta in deltas {
                apply_delta(textures, *id, delta);
            }
        }
        full.textures_delta.clear();
        full
    };
    pass();
    let full = pass();
    (full, bottom)
}

/// Renders and writes the PNG (a job's work).
pub fn run_png_export(
    request: PngRequest,
    context: &JobContext<PngOutcome>,
) -> Result<PngOutcome, JobStop> {
    context.progress("drawing", Some(0.1));
    let canvas = match &request.figure {
        PngFigure::Trends { view, size } => render_trends(view, request.dark, *size),
        PngFigure::Discrepancy { view, width } => {
            Ok(render_discrepancy(view, request.dark, *width))
        }
    }
    .map_err(|e| JobStop::Failed(e.to_string()))?;
    context.check()?;
    context.progress("writing the PNG", Some(0.8));
    canvas
        .save_png(&request.path)
        .map_err(|e| JobStop::Failed(e.to_string()))?;
    Ok(PngOutcome {
        path: request.path,
        size: [canvas.width(), canvas.height()],
    })
}

fn apply_delta(textures: &mut HashMap<TextureId, ColorImage>, id: TextureId, delta: &ImageDelta) {
    let egui::ImageData::Color(patch) = &delta.image;
    match delta.pos {
        None => {
            textures.insert(id, (**patch).clone());
        }
        Some([x0, y0]) => {
            if let Some(image) = textures.get_mut(&id) {
                let [w, h] = patch.size;
                for y in 0..h {
                    for x in 0..w {
                        let (tx, ty) = (x0 + x, y0 + y);
                        if tx < image.size[0] && ty < image.size[1] {
                            image.pixels[ty * image.size[0] + tx] = patch.pixels[y * w + x];
                        }
                    }
                }
            }
        }
    }
}

/// An RGBA image being drawn (premultiplied alpha, sRGB bytes, as egui's colours are).
#[derive(Debug, Clone)]
pub struct Canvas {
    width: u32,
    height: u32,
    /// Premultiplied RGBA per pixel, row by row.
    pixels: Vec<[f32; 4]>,
}

impl Canvas {
    /// A transparent canvas.
    pub fn new(width: u32, height: u32) -> Canvas {
        Canvas {
            width,
            height,
            pixels: vec![[0.0; 4]; width as usize * height as usize],
        }
    }

    /// Width, pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height, pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The pixel at (x, y) as straight (not premultiplied) RGBA bytes.
    pub fn pixel(&self, x: u32, y: u32) -> [u8; 4] {
        let p = self.pixels[(y * self.width + x) as usize];
        let a = p[3].clamp(0.0, 1.0);
        let straight = |c: f32| {
            if a > 0.0 {
                (c / a * 255.0).round().clamp(0.0, 255.0) as u8
            } else {
                0
            }
        };
        [
            straight(p[0]),
            straight(p[1]),
            straight(p[2]),
            (a * 255.0).round() as u8,
        ]
    }

    /// Encodes the canvas as PNG.
    pub fn save_png(&self, path: &Path) -> Result<(), PngError> {
        let mut bytes = Vec::with_capacity(self.pixels.len() * 4);
        for y in 0..self.height {
            for x in 0..self.width {
                bytes.extend_from_slice(&self.pixel(x, y));
            }
        }
        let error = |message: String| PngError::Write {
            path: path.display().to_string(),
            message,
        };
        let image = image::RgbaImage::from_raw(self.width, self.height, bytes)
            .ok_or_else(|| error("image buffer has the wrong size".into()))?;
        image
            .save_with_format(path, image::ImageFormat::Png)
            .map_err(|e| error(e.to_string()))
    }

    fn fill_primitive(
        &mut self,
        primitive: &ClippedPrimitive,
        ppp: f32,
        textures: &HashMap<TextureId, ColorImage>,
    ) {
        let Primitive::Mesh(mesh) = &primitive.primitive else {
            // Paint callbacks draw with a GPU; the plots use none.
            return;
        };
        let texture = textures.get(&mesh.texture_id);
        let clip = primitive.clip_rect;
        let (cx0, cy0) = (
            (clip.min.x * ppp).floor().max(0.0) as i64,
            (clip.min.y * ppp).floor().max(0.0) as i64,
        );
        let (cx1, cy1) = (
            ((clip.max.x * ppp).ceil() as i64).min(i64::from(self.width)),
            ((clip.max.y * ppp).ceil() as i64).min(i64::from(self.height)),
        );
        for triangle in mesh.indices.chunks_exact(3) {
            let v = [
                &mesh.vertices[triangle[0] as usize],
                &mesh.vertices[triangle[1] as usize],
                &mesh.vertices[triangle[2] as usize],
            ];
            self.fill_triangle(v, ppp, texture, [cx0, cy0, cx1, cy1]);
        }
    }

    fn fill_triangle(
        &mut self,
        v: [&egui::epaint::Vertex; 3],
        ppp: f32,
        texture: Option<&ColorImage>,
        clip: [i64; 4],
    ) {
        let p: Vec<(f32, f32)> = v.iter().map(|v| (v.pos.x * ppp, v.pos.y * ppp)).collect();
        let area = (p[1].0 - p[0].0) * (p[2].1 - p[0].1) - (p[2].0 - p[0].0) * (p[1].1 - p[0].1);
        if area.abs() < 1e-12 {
            return;
        }
        let min_x =
            (p.iter().map(|q| q.0).fold(f32::INFINITY, f32::min).floor() as i64).max(clip[0]);
        let max_x = (p
            .iter()
            .map(|q| q.0)
            .fold(f32::NEG_INFINITY, f32::max)
            .ceil() as i64)
            .min(clip[2]);
        let min_y =
            (p.iter().map(|q| q.1).fold(f32::INFINITY, f32::min).floor() as i64).max(clip[1]);
        let max_y = (p
            .iter()
            .map(|q| q.1)
            .fold(f32::NEG_INFINITY, f32::max)
            .ceil() as i64)
            .min(clip[3]);
        let colour = |k: usize| {
            let c = v[k].color;
            [
                f32::from(c.r()) / 255.0,
                f32::from(c.g()) / 255.0,
                f32::from(c.b()) / 255.0,
                f32::from(c.a()) / 255.0,
            ]
        };
        let colours = [colour(0), colour(1), colour(2)];
        for y in min_y..max_y {
            for x in min_x..max_x {
                // Pixel centres, as GPUs sample.
                let (px, py) = (x as f32 + 0.5, y as f32 + 0.5);
                let w0 = ((p[1].0 - px) * (p[2].1 - py) - (p[2].0 - px) * (p[1].1 - py)) / area;
                let w1 = ((p[2].0 - px) * (p[0].1 - py) - (p[0].0 - px) * (p[2].1 - py)) / area;
                let w2 = 1.0 - w0 - w1;
                if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                    continue;
                }
                let w = [w0, w1, w2];
                let mut src = [0.0f32; 4];
                for (c, slot) in src.iter_mut().enumerate() {
                    *slot = w[0] * colours[0][c] + w[1] * colours[1][c] + w[2] * colours[2][c];
                }
                if let Some(texture) = texture {
                    let u = w[0] * v[0].uv.x + w[1] * v[1].uv.x + w[2] * v[2].uv.x;
                    let t = w[0] * v[0].uv.y + w[1] * v[1].uv.y + w[2] * v[2].uv.y;
                    let texel = sample(texture, u, t);
                    for c in 0..4 {
                        src[c] *= texel[c];
                    }
                }
                let dst = &mut self.pixels[(y as u32 * self.width + x as u32) as usize];
                let keep = 1.0 - src[3];
                for c in 0..4 {
                    dst[c] = src[c] + dst[c] * keep;
                }
            }
        }
    }
}

/// Bilinear sample of a premultiplied texture at normalised (u, v).
fn sample(texture: &ColorImage, u: f32, v: f32) -> [f32; 4] {
    let [w, h] = texture.size;
    if w == 0 || h == 0 {
        return [1.0; 4];
    }
    let x = (u * w as f32 - 0.5).clamp(0.0, (w - 1) as f32);
    let y = (v * h as f32 - 0.5).clamp(0.0, (h - 1) as f32);
    let (x0, y0) = (x.floor() as usize, y.floor() as usize);
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let (fx, fy) = (x - x0 as f32, y - y0 as f32);
    let texel = |x: usize, y: usize| {
        let c = texture.pixels[y * w + x];
        [c.r(), c.g(), c.b(), c.a()].map(|b| f32::from(b) / 255.0)
    };
    let (a, b, c, d) = (texel(x0, y0), texel(x1, y0), texel(x0, y1), texel(x1, y1));
    let mut out = [0.0; 4];
    for k in 0..4 {
        out[k] =
            (a[k] * (1.0 - fx) + b[k] * fx) * (1.0 - fy) + (c[k] * (1.0 - fx) + d[k] * fx) * fy;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_triangle_covers_its_inside_and_not_its_outside() {
        let mut mesh = egui::epaint::Mesh::default();
        let red = egui::Color32::from_rgb(255, 0, 0);
        mesh.colored_vertex(egui::pos2(0.0, 0.0), red);
        mesh.colored_vertex(egui::pos2(10.0, 0.0), red);
        mesh.colored_vertex(egui::pos2(0.0, 10.0), red);
        mesh.add_triangle(0, 1, 2);
        let primitive = ClippedPrimitive {
            clip_rect: egui::Rect::EVERYTHING,
            primitive: Primitive::Mesh(mesh),
        };
        let mut canvas = Canvas::new(12, 12);
        canvas.fill_primitive(&primitive, 1.0, &HashMap::new());
        assert_eq!(canvas.pixel(1, 1), [255, 0, 0, 255]);
        assert_eq!(canvas.pixel(9, 9), [0, 0, 0, 0]);
        assert_eq!(canvas.pixel(11, 0), [0, 0, 0, 0]);
    }
}
