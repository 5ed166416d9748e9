#ifndef STRUCTGP_SRC_REPORT_REPORT_ASSETS_H_
#define STRUCTGP_SRC_REPORT_REPORT_ASSETS_H_

// The style sheet and the scripts of the HTML report (report.cc), inlined into every report so
// that it works offline. The plotting code is our own: canvas drawing, axes with 1-2-5 ticks,
// drag to zoom, double-click to reset, hover for the nearest point's values.
//
// Contract with report.cc:
//  * <div id="status" data-state data-errors data-plots data-plots-rendered> comes first in the
//    body, followed by kReportErrorScript, which counts every script error on the page into
//    data-errors (and shows them), so that a headless browser's DOM dump tells whether the page
//    worked.
//  * <script type="application/json" id="report-data"> holds {"plots": [...]}; each plot is
//    {type: "line" | "scatter", title, xLabel, yLabel, zeroLine, levels?: [{y, label}],
//    series: [{label, role, samples, x, y, lo?, hi?}]} where non-finite numbers are null (drawn
//    as gaps / skipped); levels are dashed horizontal reference lines, always in the automatic
//    y range.
//  * <div class="plot" data-plot="k"> is where plot k is drawn. After drawing, the element gets
//    data-marks (points drawn inside the view), data-levels (reference lines drawn, on plots that
//    have levels) and the status data-plots-rendered (plots with at least one mark) and
//    data-state="done".
//  * With "#selftest" in the address, every plot is zoomed, hovered and reset by synthetic
//    pointer events and the outcome written to the status's data-selftest.

namespace structgp {
namespace report {
namespace internal {

inline constexpr char kReportCss[] = R"css(
:root {
  --fg: #212529; --muted: #6c757d; --rule: #dee2e6; --head: #f8f9fa;
  --good: #2b8a3e; --good-bg: #ebfbee; --bad: #c92a2a; --bad-bg: #fff5f5;
}
* { box-sizing: border-box; }
body {
  font: 14px/1.45 system-ui, -apple-system, "Segoe UI", Roboto, "DejaVu Sans", sans-serif;
  color: var(--fg); background: #fff; max-width: 1240px; margin: 0 auto; padding: 16px 24px 48px;
}
h1 { font-size: 1.6em; margin: 0.2em 0 0.5em; }
h2 { font-size: 1.25em; margin: 1.6em 0 0.6em; padding-bottom: 0.2em;
     border-bottom: 1px solid var(--rule); }
h3 { font-size: 1.05em; margin: 1.2em 0 0.4em; }
dl.meta { display: grid; grid-template-columns: max-content 1fr; gap: 2px 14px; margin: 0; }
dl.meta dt { color: var(--muted); }
dl.meta dd { margin: 0; overflow-wrap: anywhere; }
ul.notes { margin: 0.6em 0 0; padding-left: 1.2em; }
nav { margin-top: 0.8em; }
nav a { margin-right: 12px; color: #1f6fb4; text-decoration: none; }
nav a:hover { text-decoration: underline; }
table { border-collapse: collapse; margin: 0.4em 0; font-variant-numeric: tabular-nums; }
th, td { padding: 4px 10px; border-bottom: 1px solid var(--rule); text-align: right;
         vertical-align: top; }
th { background: var(--head); font-weight: 600; }
.text { text-align: left; }
tr.total td { font-weight: 600; border-top: 2px solid var(--rule); }
.chg { display: inline-block; min-width: 3.6em; margin-left: 6px; padding: 0 4px;
       border-radius: 3px; font-size: 0.85em; text-align: right; }
.chg.better { color: var(--good); background: var(--good-bg); }
.chg.worse { color: var(--bad); background: var(--bad-bg); }
.chg.same { color: var(--muted); }
code { font-family: "DejaVu Sans Mono", Menlo, Consolas, monospace; font-size: 0.92em;
       background: #f1f3f5; padding: 1px 5px; border-radius: 3px; overflow-wrap: anywhere; }
.verdict { padding: 10px 14px; margin: 0.6em 0; border-left: 4px solid var(--muted);
           background: #f8f9fa; }
.verdict.found { border-left-color: var(--good); background: var(--good-bg); }
.verdict.big { font-size: 1.1em; padding: 12px 16px; }
.verdict .message { display: inline-block; margin-top: 4px; font-size: 0.92em; }
.verdict-explained { border-left-color: var(--good); background: var(--good-bg); }
.verdict-missing_effect { border-left-color: #1f6fb4; background: #e7f1fb; }
.verdict-coverage { border-left-color: #e8590c; background: #fff4e6; }
.verdict-unexplained { border-left-color: var(--bad); background: var(--bad-bg); }
tr.coverage td { background: #fff4e6; }
.small { font-size: 0.85em; }
.muted, .hint { color: var(--muted); }
.hint { font-size: 0.9em; }
.status.failed { display: block; margin: 8px 0; padding: 8px 12px; color: var(--bad);
                 background: var(--bad-bg); border: 1px solid var(--bad); border-radius: 4px; }
.plots { display: grid; grid-template-columns: minmax(0, 1fr) minmax(0, 1fr); gap: 14px 22px; }
.plot.wide { grid-column: 1 / -1; }
.plot-heading { grid-column: 1 / -1; font-size: 1em; margin: 0.8em 0 0; }
.plot-title { font-weight: 600; }
.plot-note { color: var(--muted); font-size: 0.85em; margin-left: 8px; font-weight: normal; }
.legend { display: flex; flex-wrap: wrap; gap: 2px 16px; font-size: 0.9em; margin: 2px 0 4px; }
.legend-item { display: inline-flex; align-items: center; gap: 6px; cursor: pointer;
               user-select: none; }
.legend-item.off { opacity: 0.4; text-decoration: line-through; }
.swatch { display: inline-block; width: 18px; height: 10px; border-radius: 2px; }
.plot-frame { position: relative; height: 260px; }
.plot.wide .plot-frame { height: 300px; }
.plot-frame canvas { position: absolute; left: 0; top: 0; width: 100%; height: 100%; }
.plot-frame canvas.overlay { cursor: crosshair; }
.tooltip { position: absolute; z-index: 2; pointer-events: none; white-space: nowrap;
           font-size: 12px; padding: 4px 8px; background: rgba(255, 255, 255, 0.96);
           border: 1px solid #adb5bd; border-radius: 4px;
           box-shadow: 0 1px 4px rgba(0, 0, 0, 0.15); }
.tooltip .name { font-weight: 600; }
footer { margin-top: 3em; color: var(--muted); font-size: 0.85em; }
@media (max-width: 820px) { .plots { grid-template-columns: minmax(0, 1fr); } }
)css";

// Runs before anything else: counts and shows every error of the page's scripts.
inline constexpr char kReportErrorScript[] = R"js(
(function () {
  'use strict';
  var status = document.getElementById('status');
  function record(message) {
    var count = Number(status.getAttribute('data-errors')) + 1;
    status.setAttribute('data-errors', String(count));
    status.hidden = false;
    status.className = 'status failed';
    var line = document.createElement('div');
    line.textContent = 'Script error: ' + message;
    status.appendChild(line);
  }
  window.addEventListener('error', function (event) {
    record(event.message || String(event.error));
  });
  window.addEventListener('unhandledrejection', function (event) {
    record(String(event.reason));
  });
})();
)js";

inline constexpr char kReportScript[] = R"js(
(function () {
  'use strict';

  // ---- constants --------------------------------------------------------------------------
  var MARGIN = {left: 68, right: 16, top: 10, bottom: 42};  // px around the plot area
  var MEASURED_COLOR = '#343a40';
  var LEVEL_COLOR = '#c92a2a';  // reference lines (levels)
  var PALETTE = ['#1f6fb4', '#e8590c', '#2b8a3e', '#7048e8', '#c2255c', '#0b7285'];
  var BAND_ALPHA = 0.18;      // opacity of the +-2 sigma bands
  var POINT_ALPHA = 0.6;      // opacity of scatter points (overplotting stays readable)
  var POINT_SIZE = 3;         // px, side of a scatter point
  var DRAG_MIN_PX = 4;        // a shorter drag is a click, not a zoom
  var HOVER_RADIUS_PX = 40;   // no tooltip for points farther than this from the pointer
  var X_TICK_SPACING_PX = 90;
  var Y_TICK_SPACING_PX = 48;
  var Y_PADDING = 0.06;       // fraction of the y span added above and below the data
  var SCATTER_X_PADDING = 0.03;

  var status = document.getElementById('status');

  // ---- small helpers ----------------------------------------------------------------------
  function isNum(v) { return typeof v === 'number' && isFinite(v); }

  function element(tag, className, text) {
    var e = document.createElement(tag);
    if (className) e.className = className;
    if (text !== undefined) e.textContent = text;
    return e;
  }

  // Reports an error through the page's error handler (first script) and the console.
  function fail(error) {
    console.error(error);
    window.dispatchEvent(new ErrorEvent('error', {
      message: String((error && error.stack) || error), error: error}));
  }

  function formatValue(v) {
    if (!isNum(v)) return '\u2013';
    return String(Number(v.toPrecision(5)));
  }

  // Ticks at 1, 2 or 5 times a power of ten, about `count` of them over [lo, hi].
  function niceTicks(lo, hi, count) {
    var raw = (hi - lo) / Math.max(1, count);
    var magnitude = Math.pow(10, Math.floor(Math.log10(raw)));
    var r = raw / magnitude;
    var step = magnitude * (r < 1.5 ? 1 : r < 3 ? 2 : r < 7 ? 5 : 10);
    var values = [];
    var first = Math.ceil(lo / step - 1e-9), last = Math.floor(hi / step + 1e-9);
    for (var i = first; i <= last; ++i) values.push(i * step);
    return {step: step, values: values};
  }

  function formatTick(v, step) {
    if (Math.abs(v) < step * 1e-6) return '0';
    var a = Math.abs(v);
    if (a >= 1e5 || a < 1e-3) {
      var digits = Math.floor(Math.log10(a)) - Math.floor(Math.log10(step) + 1e-9);
      return v.toExponential(Math.max(0, Math.min(6, digits)));
    }
    return v.toFixed(Math.max(0, Math.min(10, -Math.floor(Math.log10(step) + 1e-9))));
  }

  // The smallest and largest finite values added.
  function Extent() { this.lo = Infinity; this.hi = -Infinity; }
  Extent.prototype.add = function (v) {
    if (!isNum(v)) return;
    if (v < this.lo) this.lo = v;
    if (v > this.hi) this.hi = v;
  };

  // [lo, hi] widened by `fraction` of the span on each side; a sensible range for a single
  // value or for no value at all.
  function padded(extent, fraction) {
    var lo = extent.lo, hi = extent.hi;
    if (!(lo <= hi)) return [0, 1];
    var span = hi - lo;
    if (span <= 1e-12 * Math.max(Math.abs(lo), Math.abs(hi))) {
      var d = lo !== 0 ? Math.abs(lo) * 0.1 : 1;
      return [lo - d, hi + d];
    }
    return [lo - fraction * span, hi + fraction * span];
  }

  // ---- one plot ---------------------------------------------------------------------------
  function Plot(container, spec) {
    this.container = container;
    this.spec = spec;
    this.scatter = spec.type === 'scatter';
    this.visible = spec.series.map(function () { return true; });
    this.colors = [];
    var next = 0;
    for (var i = 0; i < spec.series.length; ++i) {
      this.colors.push(spec.series[i].role === 'measured'
                           ? MEASURED_COLOR : PALETTE[next++ % PALETTE.length]);
    }
    this.view = null;  // null: everything; else {x: [lo, hi], y: [lo, hi] or null (automatic)}
    this.current = null;
    this.drag = null;
    this.marks = 0;
    this.build();
  }

  Plot.prototype.build = function () {
    var self = this, spec = this.spec;
    var title = element('div', 'plot-title', spec.title);
    var shown = 0, samples = 0;
    spec.series.forEach(function (s) { shown += s.x.length; samples += s.samples; });
    if (shown < samples) {
      title.appendChild(element('span', 'plot-note',
                                'showing ' + shown + ' of ' + samples + ' points (extremes kept)'));
    }
    this.container.appendChild(title);

    var legend = element('div', 'legend');
    spec.series.forEach(function (s, i) {
      var item = element('span', 'legend-item');
      var swatch = element('span', 'swatch');
      swatch.style.background = self.colors[i];
      item.appendChild(swatch);
      item.appendChild(document.createTextNode(s.label + (s.lo ? ' (\u00b12\u03c3)' : '')));
      item.title = 'Click to hide or show';
      item.addEventListener('click', function () {
        self.visible[i] = !self.visible[i];
        item.classList.toggle('off', !self.visible[i]);
        self.draw();
      });
      legend.appendChild(item);
    });
    this.container.appendChild(legend);

    this.frame = element('div', 'plot-frame');
    this.canvas = element('canvas');
    this.overlay = element('canvas', 'overlay');
    this.tooltip = element('div', 'tooltip');
    this.tooltip.hidden = true;
    this.frame.appendChild(this.canvas);
    this.frame.appendChild(this.overlay);
    this.frame.appendChild(this.tooltip);
    this.container.appendChild(this.frame);

    this.overlay.addEventListener('pointerdown', function (e) { self.onDown(e); });
    this.overlay.addEventListener('pointermove', function (e) { self.onMove(e); });
    this.overlay.addEventListener('pointerleave', function () {
      if (!self.drag) self.hideHover();
    });
    window.addEventListener('pointerup', function (e) { self.onUp(e); });
    this.overlay.addEventListener('dblclick', function () { self.reset(); });
  };

  // Extent of the visible data along x, or along y for the samples whose x is in xWindow.
  Plot.prototype.extent = function (axis, xWindow) {
    var e = new Extent();
    for (var i = 0; i < this.spec.series.length; ++i) {
      if (!this.visible[i]) continue;
      var s = this.spec.series[i];
      for (var k = 0; k < s.x.length; ++k) {
        var x = s.x[k];
        if (!isNum(x)) continue;
        if (axis === 'x') {
          if (isNum(s.y[k])) e.add(x);
          continue;
        }
        if (xWindow && (x < xWindow[0] || x > xWindow[1])) continue;
        e.add(s.y[k]);
        if (s.lo) { e.add(s.lo[k]); e.add(s.hi[k]); }
      }
    }
    return e;
  };

  Plot.prototype.computeView = function () {
    var x = this.view ? this.view.x
                      : padded(this.extent('x'), this.scatter ? SCATTER_X_PADDING : 0);
    var y = this.view && this.view.y ? this.view.y : null;
    if (!y) {
      var e = this.extent('y', this.view ? x : null);
      (this.spec.levels || []).forEach(function (level) { e.add(level.y); });
      y = padded(e, Y_PADDING);
    }
    return {x: x, y: y};
  };

  Plot.prototype.sx = function (x) {
    var v = this.current.x, a = this.area;
    return a.left + (x - v[0]) / (v[1] - v[0]) * a.width;
  };
  Plot.prototype.sy = function (y) {
    var v = this.current.y, a = this.area;
    return a.top + a.height - (y - v[0]) / (v[1] - v[0]) * a.height;
  };
  Plot.prototype.dataX = function (px) {
    var v = this.current.x, a = this.area;
    return v[0] + (px - a.left) / a.width * (v[1] - v[0]);
  };
  Plot.prototype.dataY = function (py) {
    var v = this.current.y, a = this.area;
    return v[0] + (a.top + a.height - py) / a.height * (v[1] - v[0]);
  };
  Plot.prototype.inView = function (x, y) {
    var v = this.current;
    return x >= v.x[0] && x <= v.x[1] && y >= v.y[0] && y <= v.y[1];
  };

  Plot.prototype.draw = function () {
    var width = this.frame.clientWidth, height = this.frame.clientHeight;
    if (width <= 0 || height <= 0) return;
    var ratio = window.devicePixelRatio || 1;
    [this.canvas, this.overlay].forEach(function (c) {
      c.width = Math.round(width * ratio);
      c.height = Math.round(height * ratio);
    });
    this.width = width;
    this.height = height;
    this.ratio = ratio;
    this.area = {left: MARGIN.left, top: MARGIN.top,
                 width: Math.max(10, width - MARGIN.left - MARGIN.right),
                 height: Math.max(10, height - MARGIN.top - MARGIN.bottom)};
    this.current = this.computeView();

    var ctx = this.canvas.getContext('2d');
    ctx.setTransform(ratio, 0, 0, ratio, 0, 0);
    ctx.fillStyle = '#fff';
    ctx.fillRect(0, 0, width, height);
    this.drawAxes(ctx);

    var a = this.area;
    ctx.save();
    ctx.beginPath();
    ctx.rect(a.left, a.top, a.width, a.height);
    ctx.clip();
    if (this.spec.zeroLine && this.current.y[0] < 0 && this.current.y[1] > 0) {
      var y0 = Math.round(this.sy(0)) + 0.5;
      ctx.strokeStyle = '#868e96';
      ctx.lineWidth = 1;
      ctx.setLineDash([4, 3]);
      ctx.beginPath();
      ctx.moveTo(a.left, y0);
      ctx.lineTo(a.left + a.width, y0);
      ctx.stroke();
      ctx.setLineDash([]);
    }
    this.drawLevels(ctx);
    var marks = 0, i;
    for (i = 0; i < this.spec.series.length; ++i) {
      if (this.visible[i] && this.spec.series[i].lo) this.drawBand(ctx, i);
    }
    for (i = 0; i < this.spec.series.length; ++i) {
      if (!this.visible[i]) continue;
      marks += this.scatter ? this.drawPoints(ctx, i) : this.drawLine(ctx, i);
    }
    ctx.restore();

    this.marks = marks;
    this.container.setAttribute('data-marks', String(marks));
    this.clearOverlay();
  };

  Plot.prototype.drawAxes = function (ctx) {
    var a = this.area, v = this.current, self = this;
    var xt = niceTicks(v.x[0], v.x[1], Math.max(2, Math.round(a.width / X_TICK_SPACING_PX)));
    var yt = niceTicks(v.y[0], v.y[1], Math.max(2, Math.round(a.height / Y_TICK_SPACING_PX)));
    ctx.lineWidth = 1;
    ctx.strokeStyle = '#e9ecef';
    ctx.beginPath();
    xt.values.forEach(function (x) {
      var px = Math.round(self.sx(x)) + 0.5;
      ctx.moveTo(px, a.top);
      ctx.lineTo(px, a.top + a.height);
    });
    yt.values.forEach(function (y) {
      var py = Math.round(self.sy(y)) + 0.5;
      ctx.moveTo(a.left, py);
      ctx.lineTo(a.left + a.width, py);
    });
    ctx.stroke();
    ctx.strokeStyle = '#868e96';
    ctx.strokeRect(a.left + 0.5, a.top + 0.5, a.width - 1, a.height - 1);

    ctx.fillStyle = '#495057';
    ctx.font = '11px system-ui, "DejaVu Sans", sans-serif';
    ctx.textAlign = 'center';
    ctx.textBaseline = 'top';
    xt.values.forEach(function (x) {
      ctx.fillText(formatTick(x, xt.step), self.sx(x), a.top + a.height + 4);
    });
    ctx.textAlign = 'right';
    ctx.textBaseline = 'middle';
    yt.values.forEach(function (y) {
      ctx.fillText(formatTick(y, yt.step), a.left - 5, self.sy(y));
    });

    ctx.fillStyle = '#212529';
    ctx.font = '12px system-ui, "DejaVu Sans", sans-serif';
    ctx.textAlign = 'center';
    ctx.textBaseline = 'bottom';
    ctx.fillText(this.spec.xLabel, a.left + a.width / 2, this.height - 2);
    ctx.save();
    ctx.translate(14, a.top + a.height / 2);
    ctx.rotate(-Math.PI / 2);
    ctx.textBaseline = 'middle';
    ctx.fillText(this.spec.yLabel, 0, 0);
    ctx.restore();
  };

  // Dashed horizontal reference lines with their labels (spec.levels), where in view.
  Plot.prototype.drawLevels = function (ctx) {
    var a = this.area, self = this, drawn = 0;
    (this.spec.levels || []).forEach(function (level) {
      if (!isNum(level.y) || level.y < self.current.y[0] || level.y > self.current.y[1]) return;
      ++drawn;
      var py = Math.round(self.sy(level.y)) + 0.5;
      ctx.strokeStyle = LEVEL_COLOR;
      ctx.lineWidth = 1.5;
      ctx.setLineDash([6, 4]);
      ctx.beginPath();
      ctx.moveTo(a.left, py);
      ctx.lineTo(a.left + a.width, py);
      ctx.stroke();
      ctx.setLineDash([]);
      ctx.fillStyle = LEVEL_COLOR;
      ctx.font = '11px system-ui, "DejaVu Sans", sans-serif';
      ctx.textAlign = 'right';
      ctx.textBaseline = 'bottom';
      ctx.fillText(level.label, a.left + a.width - 4, py - 2);
    });
    if (this.spec.levels) this.container.setAttribute('data-levels', String(drawn));
  };

  // Draws series i as a line broken at missing values; returns the points inside the view.
  Plot.prototype.drawLine = function (ctx, i) {
    var s = this.spec.series[i], marks = 0, pen = false;
    ctx.beginPath();
    for (var k = 0; k < s.x.length; ++k) {
      var x = s.x[k], y = s.y[k];
      if (!isNum(x) || !isNum(y)) { pen = false; continue; }
      if (pen) ctx.lineTo(this.sx(x), this.sy(y)); else ctx.moveTo(this.sx(x), this.sy(y));
      pen = true;
      if (this.inView(x, y)) ++marks;
    }
    ctx.strokeStyle = this.colors[i];
    ctx.lineWidth = s.role === 'measured' ? 1 : 1.5;
    ctx.lineJoin = 'round';
    ctx.stroke();
    return marks;
  };

  // Fills the band [lo, hi] of series i, one polygon per run of complete samples.
  Plot.prototype.drawBand = function (ctx, i) {
    var s = this.spec.series[i], n = s.x.length, k = 0, j;
    var complete = function (m) { return isNum(s.x[m]) && isNum(s.lo[m]) && isNum(s.hi[m]); };
    ctx.fillStyle = this.colors[i];
    ctx.globalAlpha = BAND_ALPHA;
    while (k < n) {
      while (k < n && !complete(k)) ++k;
      var start = k;
      while (k < n && complete(k)) ++k;
      if (k - start < 2) continue;
      ctx.beginPath();
      ctx.moveTo(this.sx(s.x[start]), this.sy(s.hi[start]));
      for (j = start + 1; j < k; ++j) ctx.lineTo(this.sx(s.x[j]), this.sy(s.hi[j]));
      for (j = k - 1; j >= start; --j) ctx.lineTo(this.sx(s.x[j]), this.sy(s.lo[j]));
      ctx.closePath();
      ctx.fill();
    }
    ctx.globalAlpha = 1;
  };

  Plot.prototype.drawPoints = function (ctx, i) {
    var s = this.spec.series[i], marks = 0, half = POINT_SIZE / 2;
    ctx.fillStyle = this.colors[i];
    ctx.globalAlpha = POINT_ALPHA;
    for (var k = 0; k < s.x.length; ++k) {
      var x = s.x[k], y = s.y[k];
      if (!isNum(x) || !isNum(y) || !this.inView(x, y)) continue;
      ctx.fillRect(this.sx(x) - half, this.sy(y) - half, POINT_SIZE, POINT_SIZE);
      ++marks;
    }
    ctx.globalAlpha = 1;
    return marks;
  };

  // ---- interaction ------------------------------------------------------------------------
  Plot.prototype.local = function (e) {
    var r = this.overlay.getBoundingClientRect();
    return {x: e.clientX - r.left, y: e.clientY - r.top};
  };

  Plot.prototype.clamp = function (p) {
    var a = this.area;
    return {x: Math.min(Math.max(p.x, a.left), a.left + a.width),
            y: Math.min(Math.max(p.y, a.top), a.top + a.height)};
  };

  Plot.prototype.insideArea = function (p) {
    var a = this.area;
    return p.x >= a.left && p.x <= a.left + a.width && p.y >= a.top && p.y <= a.top + a.height;
  };

  Plot.prototype.overlayContext = function () {
    var ctx = this.overlay.getContext('2d');
    ctx.setTransform(this.ratio, 0, 0, this.ratio, 0, 0);
    ctx.clearRect(0, 0, this.width, this.height);
    return ctx;
  };

  Plot.prototype.clearOverlay = function () { this.overlayContext(); };

  Plot.prototype.onDown = function (e) {
    if (e.button !== 0 || !this.area) return;
    var p = this.local(e);
    if (!this.insideArea(p)) return;
    e.preventDefault();
    this.hideHover();
    this.drag = {x0: p.x, y0: p.y, x1: p.x, y1: p.y};
  };

  Plot.prototype.onMove = function (e) {
    if (!this.area) return;
    var p = this.local(e);
    if (!this.drag) { this.hover(p); return; }
    var q = this.clamp(p);
    this.drag.x1 = q.x;
    this.drag.y1 = q.y;
    var d = this.drag, a = this.area, ctx = this.overlayContext();
    var left = Math.min(d.x0, d.x1), w = Math.abs(d.x1 - d.x0);
    var top = this.scatter ? Math.min(d.y0, d.y1) : a.top;
    var h = this.scatter ? Math.abs(d.y1 - d.y0) : a.height;
    ctx.fillStyle = 'rgba(31, 111, 180, 0.12)';
    ctx.strokeStyle = 'rgba(31, 111, 180, 0.8)';
    ctx.fillRect(left, top, w, h);
    ctx.strokeRect(left + 0.5, top + 0.5, w, h);
  };

  Plot.prototype.onUp = function () {
    var d = this.drag;
    if (!d) return;
    this.drag = null;
    var wide = Math.abs(d.x1 - d.x0) >= DRAG_MIN_PX;
    var tall = Math.abs(d.y1 - d.y0) >= DRAG_MIN_PX;
    if (!wide || (this.scatter && !tall)) { this.clearOverlay(); return; }
    var x = [this.dataX(Math.min(d.x0, d.x1)), this.dataX(Math.max(d.x0, d.x1))];
    var y = this.scatter ? [this.dataY(Math.max(d.y0, d.y1)), this.dataY(Math.min(d.y0, d.y1))]
                         : null;
    this.view = {x: x, y: y};
    this.draw();
  };

  Plot.prototype.reset = function () {
    this.view = null;
    this.draw();
  };

  // The visible sample nearest to screen point p (within HOVER_RADIUS_PX), or null.
  Plot.prototype.nearest = function (p) {
    var best = null, bestDistance = HOVER_RADIUS_PX * HOVER_RADIUS_PX;
    for (var i = 0; i < this.spec.series.length; ++i) {
      if (!this.visible[i]) continue;
      var s = this.spec.series[i];
      for (var k = 0; k < s.x.length; ++k) {
        var x = s.x[k], y = s.y[k];
        if (!isNum(x) || !isNum(y) || !this.inView(x, y)) continue;
        var dx = this.sx(x) - p.x, dy = this.sy(y) - p.y, distance = dx * dx + dy * dy;
        if (distance < bestDistance) {
          bestDistance = distance;
          best = {series: i, index: k};
        }
      }
    }
    return best;
  };

  Plot.prototype.hover = function (p) {
    var hit = this.insideArea(p) ? this.nearest(p) : null;
    if (!hit) { this.hideHover(); return; }
    var s = this.spec.series[hit.series], k = hit.index;
    var px = this.sx(s.x[k]), py = this.sy(s.y[k]);

    var ctx = this.overlayContext();
    ctx.strokeStyle = this.colors[hit.series];
    ctx.lineWidth = 2;
    ctx.beginPath();
    ctx.arc(px, py, 4.5, 0, 2 * Math.PI);
    ctx.stroke();

    var tip = this.tooltip;
    tip.textContent = '';
    var name = element('div', 'name', s.label);
    name.style.color = this.colors[hit.series];
    tip.appendChild(name);
    tip.appendChild(element('div', '', this.spec.xLabel + ': ' + formatValue(s.x[k])));
    tip.appendChild(element('div', '', this.spec.yLabel + ': ' + formatValue(s.y[k])));
    if (s.lo && isNum(s.lo[k]) && isNum(s.hi[k])) {
      tip.appendChild(element('div', '', '\u00b12\u03c3: ' + formatValue((s.hi[k] - s.lo[k]) / 2)));
    }
    tip.hidden = false;
    var left = px + 12, top = py + 12;
    if (left + tip.offsetWidth > this.width) left = px - 12 - tip.offsetWidth;
    if (top + tip.offsetHeight > this.height) top = py - 12 - tip.offsetHeight;
    tip.style.left = Math.max(0, left) + 'px';
    tip.style.top = Math.max(0, top) + 'px';
  };

  Plot.prototype.hideHover = function () {
    this.tooltip.hidden = true;
    if (this.area) this.clearOverlay();
  };

  // ---- page -------------------------------------------------------------------------------
  var plots = [];

  function updateStatus() {
    var rendered = plots.filter(function (p) { return p.marks > 0; }).length;
    status.setAttribute('data-plots-rendered', String(rendered));
  }

  function drawAll() {
    plots.forEach(function (plot) {
      try { plot.draw(); } catch (error) { fail(error); }
    });
    updateStatus();
  }

  // Zooms, hovers and resets every plot with synthetic pointer events (address "#selftest").
  function selfTest() {
    var failures = [];
    plots.forEach(function (plot, index) {
      var box = plot.overlay.getBoundingClientRect(), a = plot.area;
      var at = function (fx, fy) {
        return {clientX: box.left + a.left + fx * a.width,
                clientY: box.top + a.top + fy * a.height};
      };
      var fire = function (target, type, point) {
        var init = {bubbles: true, cancelable: true, button: 0, buttons: 1, pointerId: 1,
                    isPrimary: true, pointerType: 'mouse',
                    clientX: point.clientX, clientY: point.clientY};
        target.dispatchEvent(type === 'dblclick' ? new MouseEvent(type, init)
                                                 : new PointerEvent(type, init));
      };
      var full = plot.current;
      fire(plot.overlay, 'pointerdown', at(0.3, 0.1));
      fire(plot.overlay, 'pointermove', at(0.5, 0.5));
      fire(plot.overlay, 'pointermove', at(0.6, 0.9));
      fire(window, 'pointerup', at(0.6, 0.9));
      var zoomed = plot.current;
      if (!(zoomed.x[0] > full.x[0] && zoomed.x[1] < full.x[1])) {
        failures.push('plot ' + index + ': dragging did not zoom');
      }
      if (!plot.scatter && plot.marks === 0) failures.push('plot ' + index + ': zoom is empty');
      fire(plot.overlay, 'dblclick', at(0.5, 0.5));
      if (plot.current.x[0] !== full.x[0] || plot.current.x[1] !== full.x[1]) {
        failures.push('plot ' + index + ': double-click did not reset');
      }
      // Hover right over a drawn sample: the tooltip must show.
      var s = plot.spec.series[0], k = Math.floor(s.x.length / 2);
      while (k < s.x.length && !(isNum(s.x[k]) && isNum(s.y[k]))) ++k;
      if (k < s.x.length) {
        fire(plot.overlay, 'pointermove', {clientX: box.left + plot.sx(s.x[k]),
                                           clientY: box.top + plot.sy(s.y[k])});
        if (plot.tooltip.hidden || !plot.tooltip.textContent) {
          failures.push('plot ' + index + ': no tooltip on hover');
        }
        plot.hideHover();
      }
    });
    status.setAttribute('data-selftest', failures.length ? 'failed' : 'passed');
    if (failures.length) fail(new Error(failures.join('; ')));
  }

  function main() {
    var data = JSON.parse(document.getElementById('report-data').textContent);
    var containers = document.querySelectorAll('.plot[data-plot]');
    for (var i = 0; i < containers.length; ++i) {
      var spec = data.plots[Number(containers[i].getAttribute('data-plot'))];
      try { plots.push(new Plot(containers[i], spec)); } catch (error) { fail(error); }
    }
    drawAll();
    var pending = false;
    window.addEventListener('resize', function () {
      if (pending) return;
      pending = true;
      window.requestAnimationFrame(function () {
        pending = false;
        drawAll();
      });
    });
    if (window.location.hash === '#selftest') selfTest();
    status.setAttribute('data-state', 'done');
  }

  main();
})();
)js";

}  // namespace internal
}  // namespace report
}  // namespace structgp

#endif  // STRUCTGP_SRC_REPORT_REPORT_ASSETS_H_
