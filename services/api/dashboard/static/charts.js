/* scm-calib charts: a chart spec (services/plots/chart.py, Chart.to_json) drawn as inline SVG.
 *
 * ScmCharts.render(container, spec) draws the spec's panels in a grid fitted to the
 * container's width (fewer columns on a narrow screen) and draws again when the container is
 * resized. The pointer over a panel shows the data coordinates under it and the nearest data
 * point; dragging a rectangle zooms the panel to it, a double-click (or double-tap) resets it.
 * services/plots/mpl.py draws the same spec with matplotlib, for files: the look follows it.
 */
(function () {
  "use strict";
  const NS = "http://www.w3.org/2000/svg";
  const AXIS = "#333", GRID = "#e5e5e5";
  const DASH = { dashed: "6 3", dotted: "2 2" };
  const PT = 1.33;  // px per matplotlib point (line widths)
  const MIN_COL = 280;  // px: the narrowest column; a narrower screen gets fewer columns
  const MIN_CELL = 170;  // px: a grid kept whole (reflow "none") is at least this per column
  const M = { left: 56, right: 14, top: 8, bottom: 40, title: 18, top2: 30 };  // margins [px]
  const TITLE_H = 22;
  const DRAG_MIN = 6;  // px: a shorter drag (along an axis) does not zoom (along it)
  const NEAR = 10;  // px: how close a data point must be to be read out
  let uid = 0;  // clip path ids, unique on the page

  /* ---------------------------------------------------------------- DOM helpers */
  function node(tag, attrs, parent) {
    const el = document.createElementNS(NS, tag);
    for (const k in attrs) if (attrs[k] != null) el.setAttribute(k, attrs[k]);
    if (parent) parent.appendChild(el);
    return el;
  }
  function words(parent, str, attrs) {  // text: always textContent (labels may hold "<")
    const el = node("text", attrs, parent);
    el.textContent = str;
    return el;
  }
  function centred(parent, str, cls, x, y, more) {  // a label centred at (x, y), 11 px
    const attrs = { class: cls, x, y, "text-anchor": "middle", "font-size": 11, fill: AXIS };
    return words(parent, str, Object.assign(attrs, more));
  }
  const f1 = (v) => Math.round(v * 10) / 10;  // path coordinates to 0.1 px
  const clamp = (v, lo, hi) => Math.min(hi, Math.max(lo, v));
  function fit(str, px, perChar) {  // cut a string that would not fit `px` (estimated width)
    const n = Math.floor(px / perChar);
    return str.length <= n ? str : str.slice(0, Math.max(1, n - 1)) + "…";
  }

  /* ---------------------------------------------------------------- numbers */
  const big = (v) => Math.abs(v) >= 1e4 || (v !== 0 && Math.abs(v) < 1e-3);
  function expo(v, digits) {  // 1.5e6, 2e-4: the fewest mantissa digits (up to `digits`) for v
    let s = v.toExponential(0);
    for (let p = 1; p <= digits && Math.abs(+s - v) > Math.abs(v) * 1e-9; p++) s = v.toExponential(p);
    return s.replace("e+", "e");
  }
  function num(v, sig) {  // a read-out value to `sig` significant digits, compact
    if (v === 0) return "0";
    return big(v) ? expo(v, sig - 1) : String(+v.toPrecision(sig));
  }
  function linearLabels(ticks, step) {  // one format along an axis: same decimals, or exponents
    const top = Math.max(...ticks.map(Math.abs));
    if (big(top)) return ticks.map((v) => (Math.abs(v) < step * 1e-9 ? "0" : expo(v, 6)));
    const e = Math.floor(Math.log10(step) + 1e-9), m = step / 10 ** e;
    const dec = Math.max(0, -e + (Math.abs(m - 2.5) < 1e-6 ? 1 : 0));
    return ticks.map((v) => (Math.abs(v) < step * 1e-9 ? 0 : v).toFixed(dec));
  }
  function logLabel(v) {  // 1e6, 2e-5; "0.001" .. "5000" as they are
    const k = Math.floor(Math.log10(v) + 1e-9);
    if (k >= -3 && k <= 3) return String(+v.toPrecision(6));
    return Math.round(v / 10 ** k) + "e" + k;
  }

  /* ---------------------------------------------------------------- ticks */
  function niceStep(raw, integer) {  // the smallest 1, 2, 2.5, 5 x 10^k over raw / 1.25
    const want = raw / 1.25, mag = 10 ** Math.floor(Math.log10(want));  // (up to 25 % more ticks)
    for (const s of integer ? [1, 2, 5, 10] : [1, 2, 2.5, 5, 10]) {
      if (s * mag >= want * (1 - 1e-9)) return integer ? Math.max(1, s * mag) : s * mag;
    }
    return 10 * mag;
  }
  function linearTicks(lo, hi, count, integer) {
    if (!(hi > lo)) return { ticks: [], labels: [] };
    const step = niceStep((hi - lo) / count, integer), ticks = [];
    for (let k = Math.ceil(lo / step - 1e-9); k * step <= hi + step * 1e-9; k++) ticks.push(+(k * step).toPrecision(12));
    return { ticks, labels: ticks.length ? linearLabels(ticks, step) : [] };
  }
  function logTicks(lo, hi, count) {  // decades; with 2 and 5 between them under two decades
    const a = Math.log10(lo), b = Math.log10(hi);
    let ticks = [];
    if (b - a < 2) {
      for (let k = Math.floor(a); k <= Math.ceil(b); k++) {
        for (const m of [1, 2, 5]) {
          const v = +(m * 10 ** k).toPrecision(6);
          if (v >= lo * (1 - 1e-9) && v <= hi * (1 + 1e-9)) ticks.push(v);
        }
      }
      const mantissa = (v) => Math.round(v / 10 ** Math.floor(Math.log10(v) + 1e-9));
      if (ticks.length > count + 2) ticks = ticks.filter((v) => mantissa(v) !== 2);  // too many: 1, 5
      if (ticks.length > count + 2) ticks = ticks.filter((v) => mantissa(v) === 1);
    } else {
      const k0 = Math.ceil(a - 1e-9), k1 = Math.floor(b + 1e-9);
      const every = Math.max(1, Math.ceil((k1 - k0 + 1) / count));
      for (let k = k0; k <= k1; k++) if (k % every === 0) ticks.push(+("1e" + k));
    }
    if (ticks.length < 2) return linearTicks(lo, hi, Math.min(count, 4), false);  // a narrow range
    return { ticks, labels: ticks.map(logLabel) };
  }
  function ticksFor(lim, log, integer, len, spacing) {  // about one tick per `spacing` px
    const lo = Math.min(lim[0], lim[1]), hi = Math.max(lim[0], lim[1]);
    const count = clamp(Math.round(len / spacing), 3, 5);  // -> 3 to 7 ticks
    return log ? logTicks(lo, hi, count) : linearTicks(lo, hi, count, integer);
  }

  /* ---------------------------------------------------------------- scales and limits */
  function scaleOf(lim, log, p0, p1) {  // data <-> px along one axis (log: in log10 space)
    const t = log ? Math.log10 : (v) => v;
    const a = t(lim[0]), k = (p1 - p0) / (t(lim[1]) - a);
    return {
      lim,
      log,
      px: (v) => p0 + (t(v) - a) * k,
      inv: (p) => (log ? 10 ** (a + (p - p0) / k) : a + (p - p0) / k),
      ok: (v) => v != null && (!log || v > 0),  // drawable (nulls and, on log, v <= 0 are gaps)
    };
  }

  /* the fields of each kind of layer that hold x and y values (contours: their paths) */
  const KEYS = {
    x: { line: ["x"], band: ["x"], bars: ["edges"], points: ["x"], errorbars: ["x"], vline: ["x"],
      segment: ["x0", "x1"], vspan: ["x0", "x1"], marker: ["x"] },
    y: { line: ["y"], band: ["lo", "hi"], bars: ["heights"], points: ["y"], errorbars: ["y", "lo", "hi"],
      hline: ["y"], segment: ["y"], hspan: ["y0", "y1"], marker: ["y"] },
  };
  /* an axis's limits: its lo/hi where given, else the layers' extent with 4 % padding (in log
     space on a log axis); bars on a linear y axis start at 0, with no padding below it */
  function limits(panel, which) {
    const axis = panel[which], log = axis.scale === "log";
    let lo = Infinity, hi = -Infinity, sticky = false;
    const see = (v) => { if (v != null && (!log || v > 0)) { if (v < lo) lo = v; if (v > hi) hi = v; } };
    const seeAll = (vs) => { if (Array.isArray(vs)) for (const v of vs) see(v); else see(vs); };
    for (const layer of panel.layers) {
      if (layer.kind === "contours") {
        for (const level of layer.levels) for (const path of level.paths) seeAll(path[which]);
      } else {
        for (const key of KEYS[which][layer.kind] || []) seeAll(layer[key]);
      }
      if (which === "y" && layer.kind === "bars" && !log) { see(0); sticky = true; }
    }
    const fixed = [axis.lo, axis.hi].map((v) => (v != null && (!log || v > 0) ? v : null));
    if (lo > hi) { lo = log ? 1 : 0; hi = log ? 10 : 1; }  // nothing to fit
    if (fixed[0] != null) lo = fixed[0];
    if (fixed[1] != null) hi = fixed[1];
    const t = log ? Math.log10 : (v) => v, u = log ? (v) => 10 ** v : (v) => v;
    let a = t(lo), b = t(hi);
    if (a > b && (fixed[0] == null || fixed[1] == null)) {  // one given limit beyond the data
      if (fixed[0] == null) a = b - 1; else b = a + 1;
    }
    if (a === b) {
      const w = log ? Math.log10(2) : 0.5;
      a -= w;
      b += w;
    } else {
      const pad = (b - a) * 0.04;
      if (fixed[0] == null && !(sticky && lo === 0)) a -= pad;
      if (fixed[1] == null && !(sticky && hi === 0)) b += pad;
    }
    return [+u(a).toPrecision(12), +u(b).toPrecision(12)];
  }

  /* ---------------------------------------------------------------- layers */
  function pieces(xs, ys, sx, sy) {  // a line's connected pieces as path data (nulls break it)
    const out = [], n = Math.min(xs.length, ys.length);
    let d = "";
    for (let i = 0; i < n; i++) {
      if (sx.ok(xs[i]) && sy.ok(ys[i])) d += (d ? "L" : "M") + f1(sx.px(xs[i])) + " " + f1(sy.px(ys[i]));
      else if (d) { out.push(d); d = ""; }
    }
    if (d) out.push(d);
    return out;
  }
  function symbolAt(x, y, shape, r) {  // a small square, triangle or (else) circle
    const r2 = 2 * r;
    if (shape === "s") return `M${x - r} ${y - r}h${r2}v${r2}h${-r2}Z`;
    if (shape === "^") return `M${x} ${y - r}l${r} ${f1(r2 * 0.87)}h${-r2}Z`;
    return `M${x - r} ${y}a${r} ${r} 0 1 0 ${r2} 0a${r} ${r} 0 1 0 ${-r2} 0`;
  }
  function symbols(xs, ys, sx, sy, shape, r) {  // one path of many symbols
    const parts = [], n = Math.min(xs.length, ys.length);
    for (let i = 0; i < n; i++) {
      if (sx.ok(xs[i]) && sy.ok(ys[i])) parts.push(symbolAt(f1(sx.px(xs[i])), f1(sy.px(ys[i])), shape, r));
    }
    return parts.join("");
  }
  /* an errorbars layer's bar i is drawn (and read out) when its x, y, lo and hi all are */
  const barOk = (d, i, sx, sy) => sx.ok(d.x[i]) && sy.ok(d.y[i]) && sy.ok(d.lo[i]) && sy.ok(d.hi[i]);
  const CAP = 3, TICK = 5;  // px: half-widths of an error bar's caps and of its tick at y
  function layerGroup(g, d, attrs) {
    return node("g", Object.assign({ class: "layer layer-" + d.kind }, attrs), g);
  }
  function stroked(kind, d, path) {  // a line of a layer's colour, width and dash
    return { class: "layer layer-" + kind, d: path, stroke: d.color, "stroke-width": d.width * PT,
      "stroke-dasharray": DASH[d.dash], fill: "none" };
  }
  function shaded(kind, d, x, y, width, height) {  // a strip of a layer's colour and opacity
    return { class: "layer layer-" + kind, x: f1(x), y: f1(y), width: f1(width), height: f1(height),
      fill: d.color, "fill-opacity": d.opacity };
  }

  /* each kind of layer drawn into the panel's clipped group g (plot: the plot area) */
  const LAYERS = {
    line(g, d, sx, sy) {
      const lg = layerGroup(g, d, Object.assign(stroked("line", d), { opacity: d.opacity, "stroke-linejoin": "round" }));
      for (const piece of pieces(d.x, d.y, sx, sy)) node("path", { d: piece }, lg);
      if (d.marker) node("path", { d: symbols(d.x, d.y, sx, sy, d.marker, 2.5), fill: d.color, stroke: "none" }, lg);
    },
    band(g, d, sx, sy) {  // the area between lo and hi: one polygon per connected piece
      const bg = layerGroup(g, d, { fill: d.color, "fill-opacity": d.opacity, stroke: "none" });
      let top = [], bottom = [];
      const flush = () => {
        if (top.length > 1) node("path", { d: "M" + top.join("L") + "L" + bottom.reverse().join("L") + "Z" }, bg);
        top = [];
        bottom = [];
      };
      for (let i = 0; i < d.x.length; i++) {
        if (sx.ok(d.x[i]) && sy.ok(d.lo[i]) && sy.ok(d.hi[i])) {
          const x = f1(sx.px(d.x[i]));
          top.push(x + " " + f1(sy.px(d.hi[i])));
          bottom.push(x + " " + f1(sy.px(d.lo[i])));
        } else flush();
      }
      flush();
    },
    bars(g, d, sx, sy, plot) {  // a histogram: filled rectangles, or its step outline
      const base = f1(sy.log ? plot.y + plot.h + 2 : sy.px(0)), e = d.edges, h = d.heights;
      let path = "", open = false;
      for (let i = 0; i < h.length; i++) {
        if (!(sx.ok(e[i]) && sx.ok(e[i + 1]) && sy.ok(h[i]))) {
          if (open) path += "V" + base;
          open = false;
          continue;
        }
        const x0 = f1(sx.px(e[i])), x1 = f1(sx.px(e[i + 1])), y = f1(sy.px(h[i]));
        if (d.fill) path += `M${x0} ${base}V${y}H${x1}V${base}Z`;
        else { path += (open ? "" : `M${x0} ${base}`) + `V${y}H${x1}`; open = true; }
      }
      if (open) path += "V" + base;
      const look = d.fill ? { fill: d.color, "fill-opacity": d.opacity, stroke: "none" }
        : { fill: "none", stroke: d.color, "stroke-opacity": d.opacity, "stroke-width": 1.4 * PT };
      node("path", Object.assign({ class: "layer layer-bars", d: path }, look), g);
    },
    points(g, d, sx, sy) {  // one path of circles (or squares): thousands of points, one DOM node
      const path = symbols(d.x, d.y, sx, sy, d.symbol || "o", d.size);
      node("path", { class: "layer layer-points", d: path, fill: d.color, "fill-opacity": d.opacity }, g);
    },
    errorbars(g, d, sx, sy) {  // at each x a bar lo..hi with caps, a wider tick at y: one path
      let path = "";
      for (let i = 0; i < d.x.length; i++) {
        if (!barOk(d, i, sx, sy)) continue;
        const x = f1(sx.px(d.x[i])), y = f1(sy.px(d.y[i])), lo = f1(sy.px(d.lo[i])), hi = f1(sy.px(d.hi[i]));
        path += `M${x} ${lo}V${hi}M${f1(x - CAP)} ${lo}h${2 * CAP}M${f1(x - CAP)} ${hi}h${2 * CAP}`;
        path += `M${f1(x - TICK)} ${y}h${2 * TICK}`;
      }
      node("path", Object.assign(stroked("errorbars", d, path), { opacity: d.opacity }), g);
    },
    contours(g, d, sx, sy) {  // one path per level, in the level's colour
      const cg = layerGroup(g, d, { fill: "none", "stroke-width": d.width * PT, "stroke-linejoin": "round" });
      for (const level of d.levels) {
        const path = level.paths.map((p) => pieces(p.x, p.y, sx, sy).join("")).join("");
        if (path) node("path", { d: path, stroke: level.color }, cg);
      }
    },
    vline(g, d, sx, sy, plot) {
      if (sx.ok(d.x)) node("path", stroked("vline", d, `M${f1(sx.px(d.x))} ${plot.y}v${plot.h}`), g);
    },
    hline(g, d, sx, sy, plot) {
      if (sy.ok(d.y)) node("path", stroked("hline", d, `M${plot.x} ${f1(sy.px(d.y))}h${plot.w}`), g);
    },
    segment(g, d, sx, sy) {
      if (!(sx.ok(d.x0) && sx.ok(d.x1) && sy.ok(d.y))) return;
      node("path", stroked("segment", d, `M${f1(sx.px(d.x0))} ${f1(sy.px(d.y))}H${f1(sx.px(d.x1))}`), g);
    },
    vspan(g, d, sx, sy, plot) {
      if (!(sx.ok(d.x0) && sx.ok(d.x1))) return;
      const a = sx.px(d.x0), b = sx.px(d.x1);
      node("rect", shaded("vspan", d, Math.min(a, b), plot.y, Math.abs(b - a), plot.h), g);
    },
    hspan(g, d, sx, sy, plot) {
      if (!(sy.ok(d.y0) && sy.ok(d.y1))) return;
      const a = sy.px(d.y0), b = sy.px(d.y1);
      node("rect", shaded("hspan", d, plot.x, Math.min(a, b), plot.w, Math.abs(b - a)), g);
    },
    marker(g, d, sx, sy) {  // "+" (a plus sign `size` px across); other symbols as a dot
      if (!(sx.ok(d.x) && sy.ok(d.y))) return;
      const x = f1(sx.px(d.x)), y = f1(sy.px(d.y)), s = d.size;
      const plus = `M${x - s / 2} ${y}h${s}M${x} ${y - s / 2}v${s}`;
      if (d.symbol === "+") node("path", { class: "layer layer-marker", d: plus, stroke: d.color, "stroke-width": 2 }, g);
      else node("path", { class: "layer layer-marker", d: symbolAt(x, y, d.symbol, s / 2), fill: d.color }, g);
    },
    text(g, d, sx, sy, plot) {  // a note at fractions of the plot area (fy from the bottom)
      const x = f1(plot.x + d.fx * plot.w), y = f1(plot.y + (1 - d.fy) * plot.h);
      const t = node("text", { class: "layer layer-text", x, y, "font-size": 11, fill: AXIS }, g);
      String(d.text).split("\n").forEach((line, k) => {
        const span = node("tspan", { x, dy: k ? "1.2em" : "0.8em" }, t);
        span.textContent = line;
      });
    },
  };

  /* ---------------------------------------------------------------- legend */
  const FILLED = ["band", "bars", "vspan", "hspan"];
  function swatch(g, d, x, cy) {  // a sample of a layer's look, 14 px wide
    if (FILLED.includes(d.kind)) {
      const outline = d.kind === "bars" && !d.fill;
      node("rect", { x, y: cy - 5, width: 14, height: 10, fill: outline ? "none" : d.color,
        "fill-opacity": Math.max(d.opacity, 0.3), stroke: outline ? d.color : "none" }, g);
    } else if (d.kind === "points") {
      const look = { fill: d.color, "fill-opacity": Math.max(d.opacity, 0.6) };
      if (d.symbol === "s") node("path", Object.assign({ d: symbolAt(x + 7, cy, "s", 3) }, look), g);
      else node("circle", Object.assign({ cx: x + 7, cy, r: 3 }, look), g);
    } else if (d.kind === "errorbars") {  // a bar with caps
      node("path", { d: `M${x + 7} ${f1(cy - 5)}v10M${x + 4} ${f1(cy - 5)}h6M${x + 4} ${f1(cy + 5)}h6`, stroke: d.color,
        "stroke-width": Math.min(3, (d.width || 1) * PT), opacity: d.opacity, fill: "none" }, g);
    } else if (d.kind === "marker") {
      node("path", { d: `M${x + 2} ${cy}h10M${x + 7} ${cy - 5}v10`, stroke: d.color, "stroke-width": 2 }, g);
    } else {
      const color = d.kind === "contours" ? (d.levels[Math.floor(d.levels.length / 2)] || { color: AXIS }).color : d.color;
      node("path", { d: `M${x} ${cy}h14`, stroke: color, "stroke-width": Math.min(3, (d.width || 1) * PT),
        "stroke-dasharray": DASH[d.dash], opacity: d.opacity }, g);
      if (d.kind === "line" && d.marker) node("path", { d: symbolAt(x + 7, cy, d.marker, 2.5), fill: color }, g);
    }
  }
  const CORNERS = ["upper right", "upper left", "lower left", "lower right"];
  const placeOf = (loc) => ({  // a matplotlib loc name as fractions across and down
    fx: /left/.test(loc) ? 0 : /right/.test(loc) ? 1 : 0.5,
    fy: /upper/.test(loc) ? 0 : /lower/.test(loc) ? 1 : 0.5,
  });
  function boxAtLoc(loc, plot, w, h) {
    const { fx, fy } = placeOf(loc);
    return { x: plot.x + 4 + fx * (plot.w - w - 8), y: plot.y + 4 + fy * (plot.h - h - 8), w, h };
  }
  function bestCorner(panel, sx, sy, plot, w, h) {  // "best": the corner over fewest data points
    const boxes = CORNERS.map((c) => boxAtLoc(c, plot, w, h)), count = [0, 0, 0, 0];
    const see = (x, y) => {
      if (!sx.ok(x) || !sy.ok(y)) return;
      const X = sx.px(x), Y = sy.px(y);
      boxes.forEach((b, k) => { if (X >= b.x && X <= b.x + b.w && Y >= b.y && Y <= b.y + b.h) count[k]++; });
    };
    const seeAll = (xs, ys) => {  // at most ~2000 points a layer: enough to choose a corner
      const step = Math.max(1, Math.ceil(xs.length / 2000));
      for (let i = 0; i < xs.length; i += step) see(xs[i], ys[i]);
    };
    const seeLine = (xs, ys) => {  // a sparse line: points along its segments too
      if (xs.length > 200) return seeAll(xs, ys);
      for (let i = 0; i < xs.length; i++) {
        see(xs[i], ys[i]);
        if (!i || !sx.ok(xs[i - 1]) || !sy.ok(ys[i - 1]) || !sx.ok(xs[i]) || !sy.ok(ys[i])) continue;
        const x0 = sx.px(xs[i - 1]), y0 = sy.px(ys[i - 1]), x1 = sx.px(xs[i]), y1 = sy.px(ys[i]);
        for (let f = 0.1; f < 0.95; f += 0.1) see(sx.inv(x0 + (x1 - x0) * f), sy.inv(y0 + (y1 - y0) * f));
      }
    };
    const [xa, xb] = sx.lim, [ya, yb] = sy.lim;
    for (const d of panel.layers) {
      if (d.kind === "line") seeLine(d.x, d.y);
      else if (d.kind === "points") seeAll(d.x, d.y);
      else if (d.kind === "errorbars") { seeAll(d.x, d.y); seeAll(d.x, d.lo); seeAll(d.x, d.hi); }
      else if (d.kind === "vline") seeLine([d.x, d.x], [ya, yb]);
      else if (d.kind === "hline") seeLine([xa, xb], [d.y, d.y]);
      else if (d.kind === "segment") seeLine([d.x0, d.x1], [d.y, d.y]);
      else if (d.kind === "band") { seeAll(d.x, d.lo); seeAll(d.x, d.hi); }
      else if (d.kind === "bars") seeAll(d.edges.slice(1).map((e, i) => (e + d.edges[i]) / 2), d.heights);
      else if (d.kind === "contours") for (const l of d.levels) for (const p of l.paths) seeAll(p.x, p.y);
    }
    return CORNERS[count.indexOf(Math.min(...count))];
  }
  function legend(g, panel, sx, sy, plot) {  // the legend's loc, or null when there is none
    const items = panel.layers.filter((d) => d.label != null && d.label !== "" && d.kind !== "text");
    if (!panel.legend || !items.length) return null;
    const w = Math.min(plot.w - 8, 32 + Math.max(...items.map((d) => String(d.label).length)) * 5.6);
    const h = items.length * 14 + 6;
    const loc = panel.legend === "best" ? bestCorner(panel, sx, sy, plot, w, h) : panel.legend;
    const box = boxAtLoc(loc, plot, w, h);
    const lg = node("g", { class: "chart-legend", "pointer-events": "none", "font-size": 10 }, g);
    const frame = { x: f1(box.x), y: f1(box.y), width: f1(w), height: h, rx: 3 };
    node("rect", Object.assign(frame, { fill: "#fff", "fill-opacity": 0.8, stroke: "#ccc" }), lg);
    items.forEach((d, k) => {
      const cy = f1(box.y + 10 + 14 * k);
      swatch(lg, d, f1(box.x + 6), cy);
      words(lg, fit(String(d.label), w - 30, 5.6), { x: f1(box.x + 26), y: cy, dy: "0.35em", fill: AXIS });
    });
    return loc;
  }

  /* ---------------------------------------------------------------- a panel */
  function drawPanel(svg, box, st) {
    const p = box.panel, id = "scm-chart-clip-" + ++uid;
    const plot = {
      x: box.x + M.left, y: box.y + M.top + box.extra,
      w: Math.max(10, box.w - M.left - M.right), h: Math.max(10, box.h - M.top - box.extra - M.bottom),
    };
    if (!st.fitted.has(box.index)) st.fitted.set(box.index, { x: limits(p, "x"), y: limits(p, "y") });
    const lim = st.zoom.get(box.index) || st.fitted.get(box.index);
    const sx = scaleOf(lim.x, p.x.scale === "log", plot.x, plot.x + plot.w);
    const sy = scaleOf(lim.y, p.y.scale === "log", plot.y + plot.h, plot.y);
    const g = node("g", { class: "chart-panel", "data-panel": box.index, "data-xlim": lim.x.join(","),
      "data-ylim": lim.y.join(",") }, svg);
    const bottom = plot.y + plot.h, cx = f1(plot.x + plot.w / 2);

    // grid and ticks: x at the bottom; y on the left unless its tick labels are off (as mpl)
    const xt = ticksFor(lim.x, sx.log, p.x.integer, plot.w, 55);
    const yt = p.y.tick_labels ? ticksFor(lim.y, sy.log, p.y.integer, plot.h, 40) : { ticks: [], labels: [] };
    let grid = "", marks = "";
    for (const v of xt.ticks) {
      const X = f1(sx.px(v));
      grid += `M${X} ${plot.y}V${bottom}`;
      marks += `M${X} ${bottom}v4`;
    }
    for (const v of yt.ticks) {
      const Y = f1(sy.px(v));
      grid += `M${plot.x} ${Y}h${plot.w}`;
      marks += `M${plot.x} ${Y}h-4`;
    }
    node("path", { class: "chart-grid", d: grid, stroke: GRID, fill: "none" }, g);

    // the layers, clipped to the plot area
    const defs = node("defs", {}, g);
    node("rect", { x: plot.x, y: plot.y, width: plot.w, height: plot.h }, node("clipPath", { id }, defs));
    const lg = node("g", { class: "chart-layers", "clip-path": `url(#${id})` }, g);
    for (const d of p.layers) if (LAYERS[d.kind]) LAYERS[d.kind](lg, d, sx, sy, plot);

    const area = { x: plot.x, y: plot.y, width: plot.w, height: plot.h };
    node("rect", Object.assign({ class: "chart-frame", fill: "none", stroke: AXIS }, area), g);
    node("path", { class: "chart-tickmarks", d: marks, stroke: AXIS }, g);
    if (p.x.tick_labels) {
      const tg = node("g", { class: "chart-ticks chart-ticks-x", "text-anchor": "middle", "font-size": 10, fill: AXIS }, g);
      xt.ticks.forEach((v, k) => words(tg, xt.labels[k], { x: f1(sx.px(v)), y: bottom + 15 }));
    }
    const yg = node("g", { class: "chart-ticks chart-ticks-y", "text-anchor": "end", "font-size": 10, fill: AXIS }, g);
    yt.ticks.forEach((v, k) => words(yg, yt.labels[k], { x: plot.x - 6, y: f1(sy.px(v)), dy: "0.35em" }));
    if (p.x.label) centred(g, fit(p.x.label, plot.w + 40, 6), "chart-label chart-label-x", cx, bottom + 33);
    if (p.y.label) {
      const cy = f1(plot.y + plot.h / 2), x = box.x + 11;
      const turn = { transform: `rotate(-90 ${x} ${cy})` };
      centred(g, fit(p.y.label, plot.h + 20, 6), "chart-label chart-label-y", x, cy, turn);
    }
    if (p.top && p.top.b) drawTop(g, p.top, sx, plot);
    if (p.title) {
      centred(g, fit(p.title, plot.w + 40, 6.5), "chart-panel-title", cx, box.y + M.top + 10, { "font-weight": "bold" });
    }

    // what the pointer uses: a crosshair over the plot area, the legend above it, then reset
    node("rect", Object.assign({ class: "chart-hit", fill: "#000", "fill-opacity": 0, style: "cursor:crosshair" }, area), g);
    const loc = legend(g, p, sx, sy, plot);
    if (st.zoom.has(box.index)) {
      const left = loc != null && placeOf(loc).fx === 1 && placeOf(loc).fy === 0;  // not over it
      const bx = left ? plot.x + 4 : plot.x + plot.w - 40, by = plot.y + 4;
      const rb = node("g", { class: "chart-reset", role: "button", tabindex: 0, "aria-label": "reset zoom",
        "data-panel": box.index, style: "cursor:pointer" }, g);
      node("rect", { x: bx, y: by, width: 36, height: 16, rx: 3, fill: "#fff", stroke: "#999" }, rb);
      words(rb, "reset", { x: bx + 18, y: by + 12, "text-anchor": "middle", "font-size": 10, fill: AXIS });
    }
    return { index: box.index, panel: p, plot, sx, sy, g };
  }
  function drawTop(g, top, sx, plot) {  // a second x axis: (x - a) / b, with its own ticks
    const t = (x) => (x - top.a) / top.b, t0 = t(sx.lim[0]), t1 = t(sx.lim[1]);
    const tt = ticksFor([t0, t1], sx.log && t0 > 0 && t1 > 0, false, plot.w, 55);  // log: log ticks
    const tg = node("g", { class: "chart-ticks chart-ticks-top", "text-anchor": "middle", "font-size": 9, fill: AXIS }, g);
    let marks = "";
    tt.ticks.forEach((v, k) => {
      const x = top.a + top.b * v;
      if (!sx.ok(x)) return;
      const X = f1(sx.px(x));
      marks += `M${X} ${plot.y}v-4`;
      words(tg, tt.labels[k], { x: X, y: plot.y - 6 });
    });
    node("path", { d: marks, stroke: AXIS }, g);
    if (!top.label) return;
    const cx = f1(plot.x + plot.w / 2);
    centred(g, fit(top.label, plot.w, 5.5), "chart-label chart-label-top", cx, plot.y - 19, { "font-size": 10 });
  }

  /* ---------------------------------------------------------------- the chart */
  function contentWidth(el) {
    const cs = getComputedStyle(el);
    return Math.max(0, Math.floor(el.clientWidth - (parseFloat(cs.paddingLeft) || 0) - (parseFloat(cs.paddingRight) || 0)));
  }
  /* the grid: spec.columns, or fewer at MIN_COL px each (re-flowed in order, row by row or,
     with spec.reflow "columns", column by column, so a column's panels stay together; empty
     cells dropped; reflow "none" keeps the grid, a pair matrix's); a row's height from
     matplotlib's aspect, plus room for titles and top axes */
  function layout(spec, W) {
    const n = spec.panels.length, cols0 = Math.max(1, spec.columns || 1);
    const cols = spec.reflow === "none" ? cols0 : Math.min(cols0, Math.max(1, Math.floor(W / MIN_COL)));
    let order = spec.panels.map((p, i) => i);
    if (cols < cols0 && spec.reflow === "columns") {
      order = order.slice().sort((a, b) => (a % cols0) - (b % cols0) || a - b);
    }
    const cells = order.map((i) => (spec.panels[i] ? i : null)).filter((i) => cols === cols0 || i !== null);
    const size = spec.size || [8, 4];
    const aspect = (size[1] / Math.max(1, Math.ceil(n / cols0))) / (size[0] / cols0);
    const cw = W / cols, base = clamp(cw * aspect, 150, 340), boxes = [];
    let y = spec.title ? TITLE_H : 4;
    for (let r = 0; r * cols < cells.length; r++) {
      const row = cells.slice(r * cols, r * cols + cols);
      const room = (p) => (p && p.title ? M.title : 0) + (p && p.top ? M.top2 : 0);
      const extra = Math.max(0, ...row.map((i) => room(spec.panels[i])));
      row.forEach((i, c) => {
        if (i !== null) boxes.push({ index: i, panel: spec.panels[i], x: c * cw, y, w: cw, h: base + extra, extra });
      });
      y += base + extra;
    }
    return { boxes, height: Math.ceil(y) };
  }
  function draw(st) {
    st.width = contentWidth(st.container);
    const spec = st.spec, kept = spec.reflow === "none";
    // hidden (a closed dialog): drawn again when it shows; a grid kept whole is at least
    // MIN_CELL px a column and, wider than its box, scrolls sideways in it (the page does not)
    let W = st.width || 640;
    if (kept) W = Math.max(W, Math.max(1, spec.columns || 1) * MIN_CELL);
    st.container.style.overflowX = W > st.width ? "auto" : "";
    const lay = layout(spec, W);
    const svg = node("svg", {
      class: "chart", role: "img", "aria-label": spec.title || "chart",
      width: W, height: lay.height, viewBox: `0 0 ${W} ${lay.height}`,
      // a touch drag across zooms, one along the page scrolls it (the browser takes that)
      style: (W > st.width ? "display:block;" : "display:block;max-width:100%;height:auto;")
        + "font-family:inherit;user-select:none;-webkit-user-select:none;touch-action:pan-y pinch-zoom",
    });
    if (spec.title) {
      centred(svg, fit(spec.title, W - 8, 7), "chart-title", W / 2, 15, { "font-size": 12, "font-weight": "bold" });
    }
    st.boxes = lay.boxes.map((box) => drawPanel(svg, box, st));
    svg.setAttribute("data-ready", "1");
    if (st.svg) st.svg.replaceWith(svg); else st.container.insertBefore(svg, st.readout);
    st.svg = svg;
    st.drag = null;
  }

  /* ---------------------------------------------------------------- the pointer */
  function local(st, ev) {  // the pointer in svg coordinates
    const r = st.svg.getBoundingClientRect(), k = r.width ? st.svg.viewBox.baseVal.width / r.width : 1;
    return { x: (ev.clientX - r.left) * k, y: (ev.clientY - r.top) * k };
  }
  const inside = (pl, pt) => pt.x >= pl.x && pt.x <= pl.x + pl.w && pt.y >= pl.y && pt.y <= pl.y + pl.h;
  const boxAt = (st, pt) => st.boxes.find((b) => inside(b.plot, pt));
  /* the line, points or errorbars layers' data point (x, y) closest to pt, within NEAR px;
     an error bar's with its lo and hi */
  function nearest(b, pt) {
    let best = null, bestD = NEAR * NEAR;
    for (const d of b.panel.layers) {
      if (d.kind !== "line" && d.kind !== "points" && d.kind !== "errorbars") continue;
      const bar = d.kind === "errorbars", n = Math.min(d.x.length, d.y.length);
      for (let i = 0; i < n; i++) {
        if (bar ? !barOk(d, i, b.sx, b.sy) : !b.sx.ok(d.x[i]) || !b.sy.ok(d.y[i])) continue;
        const dx = b.sx.px(d.x[i]) - pt.x;
        if (dx * dx > bestD) continue;
        const dy = b.sy.px(d.y[i]) - pt.y, dd = dx * dx + dy * dy;
        if (dd > bestD) continue;
        bestD = dd;
        best = { label: d.label || "value", x: d.x[i], y: d.y[i] };
        if (bar) Object.assign(best, { lo: d.lo[i], hi: d.hi[i] });
      }
    }
    return best;
  }
  function readout(st, ev, pt) {
    const b = boxAt(st, pt), el = st.readout;
    if (!b) { el.hidden = true; return; }
    const p = b.panel, near = nearest(b, pt);
    let text = `${p.x.label || "x"} = ${num(b.sx.inv(pt.x), 4)}, ${p.y.label || "y"} = ${num(b.sy.inv(pt.y), 4)}`;
    if (near) text += `\n${near.label}: x = ${num(near.x, 6)}, y = ${num(near.y, 6)}`;
    if (near && near.lo != null) text += ` [${num(near.lo, 6)} … ${num(near.hi, 6)}]`;
    el.textContent = text;
    el.hidden = false;
    const cr = st.container.getBoundingClientRect(), x = ev.clientX - cr.left - st.container.clientLeft;
    const left = x + 14 + el.offsetWidth > st.container.clientWidth ? Math.max(0, x - 14 - el.offsetWidth) : x + 14;
    el.style.left = left + "px";
    el.style.top = ev.clientY - cr.top - st.container.clientTop + 14 + "px";
  }
  function unzoom(st, index) {
    if (st.zoom.delete(index)) draw(st);
  }
  /* the drag rectangle: pixel range -> data range per axis; a short side keeps that axis */
  function zoomTo(st, dr, pt) {
    const b = dr.box, xs = [dr.x0, pt.x].sort((u, v) => u - v), ys = [dr.y0, pt.y].sort((u, v) => u - v);
    const wide = xs[1] - xs[0] >= DRAG_MIN, tall = ys[1] - ys[0] >= DRAG_MIN;
    if (!wide && !tall) return false;
    const round = (v) => +v.toPrecision(8);
    st.zoom.set(b.index, {
      x: wide ? [round(b.sx.inv(xs[0])), round(b.sx.inv(xs[1]))] : b.sx.lim,
      y: tall ? [round(b.sy.inv(ys[1])), round(b.sy.inv(ys[0]))] : b.sy.lim,
    });
    draw(st);
    return true;
  }
  function listeners(st) {
    const clampTo = (pl, pt) => ({ x: clamp(pt.x, pl.x, pl.x + pl.w), y: clamp(pt.y, pl.y, pl.y + pl.h) });
    const dropDrag = () => { if (st.drag && st.drag.rect) st.drag.rect.remove(); st.drag = null; };
    return {
      pointerdown(ev) {
        if (ev.button !== 0 || !st.svg || ev.target.closest(".chart-reset")) return;
        const pt = local(st, ev), b = boxAt(st, pt);
        if (!b) return;
        st.drag = { box: b, x0: pt.x, y0: pt.y, id: ev.pointerId, rect: null };
        try { st.container.setPointerCapture(ev.pointerId); } catch (e) { /* a synthetic event */ }
      },
      pointermove(ev) {
        if (!st.svg) return;
        const pt = local(st, ev), dr = st.drag;
        if (dr && dr.id === ev.pointerId) {
          const q = clampTo(dr.box.plot, pt);
          const x = Math.min(dr.x0, q.x), y = Math.min(dr.y0, q.y), w = Math.abs(q.x - dr.x0), h = Math.abs(q.y - dr.y0);
          if (!dr.rect && (w >= DRAG_MIN || h >= DRAG_MIN)) {
            dr.rect = node("rect", { class: "chart-zoombox", fill: "#1f77b4", "fill-opacity": 0.12, stroke: "#1f77b4",
              "stroke-dasharray": "4 2", "pointer-events": "none" }, st.svg);
          }
          if (dr.rect) for (const [k, v] of Object.entries({ x, y, width: w, height: h })) dr.rect.setAttribute(k, f1(v));
        }
        readout(st, ev, pt);
      },
      pointerup(ev) {
        const dr = st.drag;
        if (!dr || dr.id !== ev.pointerId) return;
        dropDrag();
        const pt = clampTo(dr.box.plot, local(st, ev));
        if (zoomTo(st, dr, pt)) { st.readout.hidden = true; return; }
        if (ev.pointerType !== "mouse") {  // a double tap resets (dblclick is the mouse's)
          const tap = st.tap;
          st.tap = { t: ev.timeStamp, x: pt.x, y: pt.y };
          if (tap && ev.timeStamp - tap.t < 400 && Math.hypot(pt.x - tap.x, pt.y - tap.y) < 24) {
            st.tap = null;
            unzoom(st, dr.box.index);
          }
        }
      },
      pointercancel: dropDrag,  // the browser took the touch (a scroll)
      pointerleave() { st.readout.hidden = true; },
      dblclick(ev) {
        if (!st.svg || ev.target.closest(".chart-reset")) return;
        const b = boxAt(st, local(st, ev));
        if (b) unzoom(st, b.index);
      },
      click(ev) {
        const r = ev.target.closest(".chart-reset");
        if (r) unzoom(st, Number(r.getAttribute("data-panel")));
      },
      keydown(ev) {
        const r = ev.target.closest && ev.target.closest(".chart-reset");
        if (!r || (ev.key !== "Enter" && ev.key !== " ")) return;
        ev.preventDefault();
        unzoom(st, Number(r.getAttribute("data-panel")));
      },
    };
  }

  /* ---------------------------------------------------------------- the API */
  const handles = new WeakMap();  // container -> its chart, replaced by a new render
  function render(container, given) {
    const old = handles.get(container);
    if (old) old.destroy();
    const raw = typeof given === "string" ? JSON.parse(given) : given;
    const spec = Object.assign({ title: "", columns: 1, size: [8, 4] }, raw, {  // missing fields filled
      panels: (raw.panels || []).map((p) => p && Object.assign({ layers: [], legend: null, top: null, title: null }, p)),
    });
    const st = {  // zoom: panel index -> limits, kept across redraws; fitted: the spec's own
      container, spec, zoom: new Map(), fitted: new Map(), boxes: [], svg: null, width: 0, drag: null, tap: null, frame: 0,
    };
    if (getComputedStyle(container).position === "static") container.style.position = "relative";
    st.readout = document.createElement("div");
    st.readout.className = "chart-readout";
    st.readout.setAttribute("role", "status");
    st.readout.hidden = true;
    Object.assign(st.readout.style, {
      position: "absolute", zIndex: "5", pointerEvents: "none", whiteSpace: "pre", background: "#13294b", color: "#fff",
      font: "12px/1.3 system-ui, sans-serif", padding: "2px 6px", borderRadius: "3px",
    });
    container.replaceChildren(st.readout);
    draw(st);
    // a new width draws again (zoom kept), once per frame; a new height alone does not
    const ro = typeof ResizeObserver === "function" ? new ResizeObserver(() => {
      if (contentWidth(container) === st.width || st.frame) return;
      st.frame = requestAnimationFrame(() => { st.frame = 0; draw(st); });
    }) : null;
    if (ro) ro.observe(container);
    const on = listeners(st);
    for (const type in on) container.addEventListener(type, on[type]);
    const handle = {
      spec: raw,
      reset() { st.zoom.clear(); draw(st); },
      destroy() {
        if (ro) ro.disconnect();
        if (st.frame) cancelAnimationFrame(st.frame);
        for (const type in on) container.removeEventListener(type, on[type]);
        if (handles.get(container) === handle) handles.delete(container);
        container.replaceChildren();
      },
    };
    handles.set(container, handle);
    return handle;
  }

  window.ScmCharts = { render };
})();
