//! The backend a figure is drawn on: a PNG bitmap or an SVG document, chosen by the file
//! name's extension ([`Backend::for_path`]). Every drawing call goes to the chosen backend's
//! own implementation, so a PNG is the bitmap backend's, pixel for pixel, and an SVG keeps
//! lines, marks and text as vector elements (text in DejaVu Sans where the viewer has it, the
//! font its layout is measured with, else in the viewer's sans-serif: [`SVG_FONT_FAMILY`]).

use std::error::Error;
use std::fmt;
use std::path::Path;

use plotters::backend::{BitMapBackend, SVGBackend};
use plotters_backend::text_anchor::Pos;
use plotters_backend::{
    BackendColor, BackendCoord, BackendStyle, BackendTextStyle, DrawingBackend, DrawingErrorKind,
    FontFamily, FontStyle, FontTransform,
};

/// The font an SVG's text names: the bundled font the figures' layout is measured with (legend
/// widths, label fitting), then the viewer's sans-serif where it lacks that one.
pub const SVG_FONT_FAMILY: &str = "DejaVu Sans, sans-serif";

/// A figure's backend: PNG or SVG.
pub enum Backend<'a> {
    /// A bitmap, written as PNG.
    Bitmap(BitMapBackend<'a>),
    /// An SVG document.
    Svg(SvgFile<'a>),
}

/// An SVG document and the file it is written to.
pub struct SvgFile<'a> {
    backend: SVGBackend<'a>,
    path: &'a Path,
    /// Whether a bitmap was embedded (then the file's data URLs are mended when written).
    embedded: bool,
}

/// How plotters' SVG backend opens an embedded PNG (a media type that is not one), and the
/// data URL's proper opening.
const PNG_DATA: (&str, &str) = ("href=\"data:png;base64,", "href=\"data:image/png;base64,");

impl SvgFile<'_> {
    /// Writes the document, every embedded bitmap marked as the PNG image it is (plotters-svg
    /// writes the file itself, so its data URLs are mended in the file, once, where it has any).
    fn present(&mut self) -> Result<(), DrawingErrorKind<BackendError>> {
        lift(self.backend.present())?;
        if !std::mem::take(&mut self.embedded) {
            return Ok(());
        }
        let io = |e| DrawingErrorKind::DrawingError(BackendError(Box::new(e)));
        let text = std::fs::read_to_string(self.path).map_err(io)?;
        std::fs::write(self.path, text.replace(PNG_DATA.0, PNG_DATA.1)).map_err(io)
    }
}

impl<'a> Backend<'a> {
    /// An SVG document if `path` ends in `.svg` (any case), else a PNG bitmap; `size` px.
    pub fn for_path(path: &'a Path, size: (u32, u32)) -> Backend<'a> {
        if is_svg(path) {
            Backend::Svg(SvgFile {
                backend: SVGBackend::new(path, size),
                path,
                embedded: false,
            })
        } else {
            Backend::Bitmap(BitMapBackend::new(path, size))
        }
    }
}

/// Whether a figure at `path` is drawn as SVG (its name ends in `.svg`, any case).
fn is_svg(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("svg"))
}

/// A drawing error of either backend, as that backend words it.
#[derive(Debug)]
pub struct BackendError(Box<dyn Error + Send + Sync>);

impl fmt::Display for BackendError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.0.fmt(f)
    }
}

impl Error for BackendError {}

/// `r` with the backend's error as a [`BackendError`].
fn lift<T, E: Error + Send + Sync + 'static>(
    r: Result<T, DrawingErrorKind<E>>,
) -> Result<T, DrawingErrorKind<BackendError>> {
    r.map_err(|e| match e {
        DrawingErrorKind::DrawingError(e) => {
            DrawingErrorKind::DrawingError(BackendError(Box::new(e)))
        }
        DrawingErrorKind::FontError(e) => DrawingErrorKind::FontError(e),
    })
}

/// `$call` on the chosen backend (`b`), its error lifted.
macro_rules! each {
    ($self:ident, $b:ident => $call:expr) => {
        match $self {
            Backend::Bitmap($b) => lift($call),
            Backend::Svg(SvgFile { backend: $b, .. }) => lift($call),
        }
    };
}

impl DrawingBackend for Backend<'_> {
    type ErrorType = BackendError;

    fn get_size(&self) -> (u32, u32) {
        match self {
            Backend::Bitmap(b) => b.get_size(),
            Backend::Svg(f) => f.backend.get_size(),
        }
    }

    fn ensure_prepared(&mut self) -> Result<(), DrawingErrorKind<BackendError>> {
        each!(self, b => b.ensure_prepared())
    }

    fn present(&mut self) -> Result<(), DrawingErrorKind<BackendError>> {
        match self {
            Backend::Bitmap(b) => lift(b.present()),
            Backend::Svg(f) => f.present(),
        }
    }

    fn draw_pixel(
        &mut self,
        point: BackendCoord,
        color: BackendColor,
    ) -> Result<(), DrawingErrorKind<BackendError>> {
        each!(self, b => b.draw_pixel(point, color))
    }

    fn draw_line<S: BackendStyle>(
        &mut self,
        from: BackendCoord,
        to: BackendCoord,
        style: &S,
    ) -> Result<(), DrawingErrorKind<BackendError>> {
        each!(self, b => b.draw_line(from, to, style))
    }

    fn draw_rect<S: BackendStyle>(
        &mut self,
        upper_left: BackendCoord,
        bottom_right: BackendCoord,
        style: &S,
        fill: bool,
    ) -> Result<(), DrawingErrorKind<BackendError>> {
        match self {
            // The SVG backend gives a rectangle's outline no width: a wider one as a path,
            // once round and on along the first side, so that every corner is a join.
            Backend::Svg(SvgFile { backend: b, .. }) if !fill && style.stroke_width() > 1 => {
                let ((x0, y0), (x1, y1)) = (upper_left, bottom_right);
                let round = [(x0, y0), (x1, y0), (x1, y1), (x0, y1), (x0, y0), (x1, y0)];
                lift(b.draw_path(round, style))
            }
            _ => each!(self, b => b.draw_rect(upper_left, bottom_right, style, fill)),
        }
    }

    fn draw_path<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
        &mut self,
        path: I,
        style: &S,
    ) -> Result<(), DrawingErrorKind<BackendError>> {
        each!(self, b => b.draw_path(path, style))
    }

    fn draw_circle<S: BackendStyle>(
        &mut self,
        center: BackendCoord,
        radius: u32,
        style: &S,
        fill: bool,
    ) -> Result<(), DrawingErrorKind<BackendError>> {
        each!(self, b => b.draw_circle(center, radius, style, fill))
    }

    fn fill_polygon<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
        &mut self,
        vert: I,
        style: &S,
    ) -> Result<(), DrawingErrorKind<BackendError>> {
        each!(self, b => b.fill_polygon(vert, style))
    }

    fn draw_text<S: BackendTextStyle>(
        &mut self,
        text: &str,
        style: &S,
        pos: BackendCoord,
    ) -> Result<(), DrawingErrorKind<BackendError>> {
        match self {
            Backend::Bitmap(b) => lift(b.draw_text(text, style, pos)),
            Backend::Svg(f) => lift(f.backend.draw_text(text, &Typeface(style), pos)),
        }
    }

    fn estimate_text_size<S: BackendTextStyle>(
        &self,
        text: &str,
        style: &S,
    ) -> Result<(u32, u32), DrawingErrorKind<BackendError>> {
        each!(self, b => b.estimate_text_size(text, style))
    }

    fn blit_bitmap(
        &mut self,
        pos: BackendCoord,
        size: (u32, u32),
        src: &[u8],
    ) -> Result<(), DrawingErrorKind<BackendError>> {
        if let Backend::Svg(f) = self {
            f.embedded = true;
        }
        each!(self, b => b.blit_bitmap(pos, size, src))
    }
}

/// A text style as the SVG document names its font ([`SVG_FONT_FAMILY`]); everything else, the
/// layout included, is the style's own.
struct Typeface<'s, S>(&'s S);

impl<S: BackendTextStyle> BackendTextStyle for Typeface<'_, S> {
    type FontError = S::FontError;

    fn color(&self) -> BackendColor {
        self.0.color()
    }

    fn size(&self) -> f64 {
        self.0.size()
    }

    fn transform(&self) -> FontTransform {
        self.0.transform()
    }

    fn style(&self) -> FontStyle {
        self.0.style()
    }

    fn anchor(&self) -> Pos {
        self.0.anchor()
    }

    fn family(&self) -> FontFamily<'_> {
        FontFamily::Name(SVG_FONT_FAMILY)
    }

    fn layout_box(&self, text: &str) -> Result<((i32, i32), (i32, i32)), Self::FontError> {
        self.0.layout_box(text)
    }

    fn draw<E, F: FnMut(i32, i32, BackendColor) -> Result<(), E>>(
        &self,
        text: &str,
        pos: BackendCoord,
        draw: F,
    ) -> Result<Result<(), E>, Self::FontError> {
        self.0.draw(text, pos, draw)
    }
}
