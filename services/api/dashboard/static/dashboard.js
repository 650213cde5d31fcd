/* scm-calib dashboard: the token, conditional polling, figures and writes.
 *
 * The API token is kept in sessionStorage (this tab only) and sent as a Bearer header with
 * every htmx request, figure and download (reads need it when the server says so) and with
 * the writes (cancel, upload, new study), which go to the JSON API.
 * Live fragments carry their ETag in data-etag; polls send it as If-None-Match and a 304
 * leaves the page as it is.
 */
(function () {
  "use strict";
  const KEY = "scm-calib-token";
  const token = () => sessionStorage.getItem(KEY) || "";
  const authHeaders = () => (token() ? { Authorization: "Bearer " + token() } : {});

  function showTokenState() {
    const el = document.getElementById("token-state");
    if (el) el.textContent = token() ? "token set for this tab" : "no token";
    // forms that write say where the token goes while there is none
    document.querySelectorAll(".token-hint").forEach((hint) => { hint.hidden = !!token(); });
  }

  function say(el, text, bad) {
    if (!el) return;
    el.textContent = text;
    el.classList.toggle("error", !!bad);
  }

  async function detailOf(resp) {
    try {
      const body = await resp.json();
      return body.detail || resp.statusText;
    } catch (e) {
      return resp.status + " " + resp.statusText;
    }
  }

  /* figures: fetched with the token, shown from a blob URL; at most FIGURE_FETCHES at a time,
     so that a stage's figures being drawn never hold all of the browser's six connections to
     the server and the progress polls wait behind them */
  const FIGURE_FETCHES = 2;
  let fetching = 0;
  const waiting = [];
  async function figureSlot() {
    if (fetching < FIGURE_FETCHES) { fetching += 1; return; }
    await new Promise((resolve) => waiting.push(resolve));  // the slot is handed over
  }
  function releaseSlot() {
    const next = waiting.shift();
    if (next) next(); else fetching -= 1;
  }
  const shown = new Map();
  const charts = new Map();  // chart box -> its drawn chart (charts.js handle)
  /* a figure whose fragment a newer one replaced (a later stage, the study's end) is not
     fetched any more: queued ones are skipped, those in flight aborted, so the newest
     stage's figures never wait behind stale ones */
  const inflight = new Map();
  function dropStale() {
    for (const [el, ctl] of inflight) if (!el.isConnected) ctl.abort();
    for (const [box, chart] of charts) if (!box.isConnected) { chart.destroy(); charts.delete(box); }
  }
  /* fetch src for el (an img or a chart box) in a figure slot and show it (show(resp)) */
  async function loadInto(el, src, show) {
    if (!src || el.dataset.loaded === src) return;
    el.dataset.loaded = src;
    el.classList.add("loading");
    await figureSlot();
    const ctl = new AbortController();
    try {
      if (!el.isConnected || el.dataset.loaded !== src) return;
      inflight.set(el, ctl);
      const resp = await fetch(src, { headers: authHeaders(), signal: ctl.signal });
      if (!resp.ok) {
        el.classList.remove("loading");
        el.replaceWith(Object.assign(document.createElement("p"), {
          className: "error figure-error",
          textContent: "figure unavailable: " + (await detailOf(resp)),
        }));
        return;
      }
      await show(resp);
    } catch (err) {
      if (err.name !== "AbortError") throw err;
    } finally {
      inflight.delete(el);
      releaseSlot();
      el.classList.remove("loading");
    }
  }
  const loadFigure = (img) => loadInto(img, img.dataset.src, async (resp) => {
    const blob = await resp.blob();
    img.dataset.axes = blob.type.startsWith("image/svg") ? axesOf(await blob.text()) : "";
    const url = URL.createObjectURL(blob);
    const old = shown.get(img);
    img.src = url;
    shown.set(img, url);
    if (old) URL.revokeObjectURL(old);
  });
  /* a chart: its data (services.plots.chart) drawn in the page by charts.js, which fits it to
     the page's width and gives it hover values and box zoom */
  const PX_PER_INCH = 120;  // a chart is at most as wide as its file's drawing (spec.size, inches)
  const loadChart = (box) => loadInto(box, box.dataset.chart, async (resp) => {
    const spec = await resp.json();
    box.style.maxWidth = Math.round(spec.size[0] * PX_PER_INCH) + "px";
    const old = charts.get(box);
    if (old) old.destroy();
    charts.set(box, window.ScmCharts.render(box, spec));
    box.dataset.drawn = box.dataset.chart;
  });

  /* hover readout: an SVG figure carries where its axes lie and their limits
     (<metadata id="axes">, services.plots.figures.axes_geometry); the pointer over a figure, or
     over its enlarged copy, shows the data coordinates under it */
  function axesOf(svg) {
    const m = /<metadata id="axes">([^<]*)<\/metadata>/.exec(svg);
    return m ? m[1] : "";
  }
  function along(f, lim, scale) {  // f: fraction of the axis from its low-value end
    if (scale === "log") return Math.pow(10, Math.log10(lim[0]) + f * (Math.log10(lim[1]) - Math.log10(lim[0])));
    return lim[0] + f * (lim[1] - lim[0]);
  }
  function short(v) { return Math.abs(v) >= 1e4 || (v !== 0 && Math.abs(v) < 1e-3) ? v.toExponential(3) : v.toPrecision(4); }
  function readoutAt(img, clientX, clientY) {
    if (!img.dataset.axes) return null;
    const box = img.getBoundingClientRect();
    const fx = (clientX - box.left) / box.width, fy = (clientY - box.top) / box.height;
    for (const ax of JSON.parse(img.dataset.axes)) {
      const [l, t, r, b] = ax.box;
      if (fx < l || fx > r || fy < t || fy > b) continue;
      const x = along((fx - l) / (r - l), ax.x, ax.xscale), y = along((b - fy) / (b - t), ax.y, ax.yscale);
      return `${ax.xlabel || "x"} = ${short(x)}, ${ax.ylabel || "y"} = ${short(y)}`;
    }
    return null;
  }
  function readoutBox() {
    let el = document.getElementById("figure-readout");
    if (!el) {
      el = Object.assign(document.createElement("div"), { id: "figure-readout", className: "figure-readout" });
      el.setAttribute("role", "status");
    }
    const host = document.querySelector("dialog[open]") || document.body;  // above a modal
    if (el.parentElement !== host) host.append(el);
    return el;
  }
  document.addEventListener("pointermove", (ev) => {
    const img = ev.target.closest && ev.target.closest("figure.fig img, dialog.figure-zoom img");
    const text = img ? readoutAt(img, ev.clientX, ev.clientY) : null;
    const el = document.getElementById("figure-readout");
    if (!text) { if (el) el.hidden = true; return; }
    const box = readoutBox();
    box.textContent = text;
    box.hidden = false;
    box.style.left = `${ev.clientX + 14}px`;
    box.style.top = `${ev.clientY + 14}px`;
  });

  /* longest to draw first (data-cost [s]), the order the server's warmer draws them in: a
     request then finds its figure being drawn instead of queueing behind the others */
  function loadFigures(root) {
    dropStale();
    const cost = (el) => parseFloat(el.dataset.cost || "0");
    [...root.querySelectorAll("img[data-src], [data-chart]")]
      .sort((a, b) => cost(b) - cost(a))
      .forEach((el) => (el.dataset.chart ? loadChart(el) : loadFigure(el)));
  }

  /* downloads: with a token, fetched and saved from a blob; without, the plain link */
  document.addEventListener("click", async (ev) => {
    const a = ev.target.closest("a[data-download]");
    if (a && token()) {
      ev.preventDefault();
      const resp = await fetch(a.href, { headers: authHeaders() });
      if (!resp.ok) return alert(await detailOf(resp));
      const url = URL.createObjectURL(await resp.blob());
      const tmp = Object.assign(document.createElement("a"), {
        href: url,
        download: a.getAttribute("download") || a.pathname.split("/").pop(),
      });
      document.body.appendChild(tmp);
      tmp.click();
      tmp.remove();
      setTimeout(() => URL.revokeObjectURL(url), 10000);
      return;
    }
    const cancel = ev.target.closest("button[data-cancel]");
    if (cancel) {
      // outside #live, so that the next poll of the live fragment keeps the message
      const out = document.getElementById("cancel-result");
      if (!token()) return say(out, "cancelling needs the API token (set it above)", true);
      const resp = await fetch("/studies/" + cancel.dataset.cancel + "/cancel", {
        method: "POST",
        headers: { ...authHeaders(), "Content-Type": "application/json" },
        body: JSON.stringify({ reason: "cancelled from the dashboard" }),
      });
      if (!resp.ok) return say(out, await detailOf(resp), true);
      say(out, "cancelled");
      htmx.ajax("GET", "/ui/f/studies/" + cancel.dataset.cancel + "/live", { target: "#live" });
    }
  });

  /* tap a figure to enlarge it: a full-screen dialog at the figure's own size or the
     screen's, whichever is wider (it scrolls in place); there the wheel (or a pinch: the
     browser's ctrl+wheel) zooms about the pointer from 1x to 8x and a drag pans; a tap that
     did not drag, or Escape, closes it */
  const ZOOM_MAX = 8;
  function zoomView(dlg) {
    const view = { s: 1, tx: 0, ty: 0, drag: null, dragged: false };
    const pic = () => dlg.querySelector("img");
    const apply = () => {
      const p = pic();
      if (!p) return;
      p.style.transform = `translate(${view.tx}px, ${view.ty}px) scale(${view.s})`;
      p.dataset.scale = view.s.toFixed(3);
    };
    view.reset = () => { view.s = 1; view.tx = 0; view.ty = 0; view.dragged = false; apply(); };
    dlg.addEventListener("wheel", (ev) => {
      const p = pic();
      if (!p) return;
      ev.preventDefault();
      const box = p.getBoundingClientRect();  // the drawn box: its origin is the translate's
      const lx = ev.clientX - (box.left - view.tx), ly = ev.clientY - (box.top - view.ty);
      const s = Math.min(Math.max(view.s * Math.exp(-ev.deltaY * 0.002), 1), ZOOM_MAX);
      view.tx = lx - (lx - view.tx) * (s / view.s);  // the point under the pointer stays
      view.ty = ly - (ly - view.ty) * (s / view.s);
      view.s = s;
      if (s === 1) { view.tx = 0; view.ty = 0; }
      apply();
    }, { passive: false });
    dlg.addEventListener("pointerdown", (ev) => {
      view.drag = { x: ev.clientX, y: ev.clientY, tx: view.tx, ty: view.ty };
      view.dragged = false;
    });
    dlg.addEventListener("pointermove", (ev) => {
      if (!view.drag || view.s === 1) return;
      const dx = ev.clientX - view.drag.x, dy = ev.clientY - view.drag.y;
      if (Math.abs(dx) + Math.abs(dy) > 4) view.dragged = true;
      view.tx = view.drag.tx + dx;
      view.ty = view.drag.ty + dy;
      apply();
    });
    dlg.addEventListener("pointerup", () => { view.drag = null; });
    dlg.addEventListener("click", () => {
      if (!view.dragged && !dlg.classList.contains("chart-zoom")) dlg.close();
      view.dragged = false;
    });
    return view;
  }
  let zoom = null;
  function zoomDialog() {
    let dlg = document.getElementById("figure-zoom");
    if (!dlg) {
      dlg = Object.assign(document.createElement("dialog"), { id: "figure-zoom", className: "figure-zoom" });
      document.body.append(dlg);
      zoom = zoomView(dlg);
    }
    return dlg;
  }
  document.addEventListener("click", (ev) => {
    const img = ev.target.closest("figure.fig img");
    if (!img || !img.src) return;
    const dlg = zoomDialog();
    const pic = Object.assign(document.createElement("img"), { src: img.src, alt: img.alt });
    pic.dataset.axes = img.dataset.axes || "";
    pic.draggable = false;
    dlg.replaceChildren(pic);
    zoom.reset();
    dlg.showModal();
  });
  /* a chart enlarged: drawn again at the screen's width (its own box zoom works there; the
     dialog closes with its button or Escape, not with a tap, which the zoom uses) */
  document.addEventListener("click", (ev) => {
    const btn = ev.target.closest("button[data-enlarge]");
    if (btn) {
      const box = btn.closest("figure.fig").querySelector("[data-chart]");
      const chart = box && charts.get(box);
      if (!chart) return;
      const dlg = zoomDialog();
      const close = Object.assign(document.createElement("button"), {
        type: "button", className: "close", textContent: "close",
      });
      close.dataset.closeDialog = "";
      const big = Object.assign(document.createElement("div"), { className: "chart-box" });
      big.setAttribute("role", "img");
      big.setAttribute("aria-label", box.getAttribute("aria-label") || "");
      dlg.replaceChildren(close, big);
      dlg.classList.add("chart-zoom");
      dlg.showModal();
      const drawn = window.ScmCharts.render(big, chart.spec);
      dlg.addEventListener("close", () => { drawn.destroy(); dlg.classList.remove("chart-zoom"); }, { once: true });
      return;
    }
    if (ev.target.closest("button[data-close-dialog]")) ev.target.closest("dialog").close();
  });

  /* a figure (img or chart) and its downloads shown with other options: swap(url) */
  function swapFigure(el, swap, alt) {
    if (el.dataset.chart) {
      el.dataset.chart = swap(el.dataset.chart);
      el.setAttribute("aria-label", alt);
    } else {
      el.dataset.src = swap(el.dataset.src);
      el.alt = alt;
    }
    el.closest("figure").querySelectorAll("a[data-download]").forEach((l) => { l.href = swap(l.getAttribute("href")); });
    if (el.dataset.chart) loadChart(el); else loadFigure(el);
  }

  /* the matrix chooser redraws the pair matrix with the checked parameters (2 to data-max) */
  document.addEventListener("change", (ev) => {
    const form = ev.target.closest("form.matrix-chooser");
    if (!form) return;
    const el = document.querySelector('figure.fig [data-figure="matrix"]');
    if (!el) return;
    const chosen = [...form.querySelectorAll("input[name=p]:checked")].map((i) => i.value);
    if (chosen.length < 2 || chosen.length > Number(form.dataset.max)) return;
    const swap = (s) => s.replace(/&p=[^&]*/, "&p=" + chosen.map(encodeURIComponent).join(","));
    swapFigure(el, swap, "Pair matrix of " + chosen.join(", "));
  });

  /* the pair chooser swaps the bivariate figure */
  document.addEventListener("change", (ev) => {
    const form = ev.target.closest("form.pair-chooser");
    if (!form) return;
    const el = document.querySelector('figure.fig [data-figure="pairs"]');
    if (!el) return;
    const a = form.elements.a.value, b = form.elements.b.value;
    if (a === b) return;
    const swap = (s) => s.replace(/&a=[^&]*&b=[^&]*/, "&a=" + encodeURIComponent(a) + "&b=" + encodeURIComponent(b));
    swapFigure(el, swap, "Bivariate posterior density of " + a + " and " + b);
  });

  /* the checked dataset ids in upload order (the likelihood's order), not the list's */
  const checkedIds = (form, name) =>
    [...form.querySelectorAll("input[name=" + name + "]:checked")].map((i) => Number(i.value)).sort((a, b) => a - b);

  const postJson = (path, body) =>
    fetch(path, {
      method: "POST",
      headers: { ...authHeaders(), "Content-Type": "application/json" },
      body: JSON.stringify(body),
    });

  /* a slip sweep of the prediction form as conditions (LO..HI in N steps at load W, the
     lab's symmetric slip, -1 locked), null when its load is empty, or a one-line error */
  const sweepConditions = (f) => {
    if (!f.sweep_w.value) return null;
    const lo = Number(f.sweep_lo.value), hi = Number(f.sweep_hi.value), n = Number(f.sweep_n.value);
    if (!(lo >= -1 && lo < hi && hi < 1) || !(n >= 2 && n <= 200)) {
      return "sweep: need -1 <= from < to < 1 and 2 to 200 slips";
    }
    return Array.from({ length: n }, (_, k) => {
      const slip = lo + ((hi - lo) * k) / (n - 1);
      return { W: Number(f.sweep_w.value), slip, slip_convention: "symmetric", name: "slip " + slip.toFixed(3) };
    });
  };

  /* a case file opened in the form fills its text box */
  document.addEventListener("change", async (ev) => {
    if (ev.target.name !== "case_file" || !ev.target.files.length) return;
    ev.target.form.elements.case_toml.value = await ev.target.files[0].text();
  });

  document.addEventListener("submit", async (ev) => {
    const form = ev.target;
    if (form.id === "token-form") {
      ev.preventDefault();
      const v = document.getElementById("token-input").value.trim();
      if (v) sessionStorage.setItem(KEY, v); else sessionStorage.removeItem(KEY);
      document.getElementById("token-input").value = "";
      showTokenState();
      // reload what a missing token kept from the page (reads may need it)
      if (document.querySelector("main .needs-token")) window.location.reload();
      return;
    }
    const out = form.querySelector(".write-result");
    if (form.id === "upload-form") {
      ev.preventDefault();
      if (!token()) return say(out, "uploading needs the API token (set it above)", true);
      const data = new FormData(form);
      for (const k of ["name", "metadata"]) if (!data.get(k)) data.delete(k);
      const resp = await fetch("/datasets", { method: "POST", headers: authHeaders(), body: data });
      if (!resp.ok) return say(out, await detailOf(resp), true);
      const d = await resp.json();
      say(out, (d.created === false ? "already stored as dataset " : "stored as dataset ") + d.id);
      form.reset();
      htmx.trigger(document.body, "uploaded");
    } else if (form.id === "new-study-form") {
      ev.preventDefault();
      if (!token()) return say(out, "starting a study needs the API token (set it above)", true);
      const f = form.elements;
      const ids = checkedIds(form, "dataset_ids");
      const body = {};
      if (f.case_toml.value.trim()) {
        // the server checks the case file as the command line does (one-line errors)
        const checked = await postJson("/cases/check", { toml: f.case_toml.value });
        if (!checked.ok) return say(out, await detailOf(checked), true);
        body.case = (await checked.json()).case;
      } else {
        body.preset = f.preset.value;
      }
      if (f.name.value) body.name = f.name.value;
      // the chosen kind: where its studies are submitted (the server's data-post), and
      // whether it is a screening (one dataset, r and levels) rather than a calibration
      const chosen = form.querySelector("input[name=kind]:checked");
      const path = chosen.dataset.post;
      if ("screening" in chosen.dataset) {
        if (ids.length !== 1) return say(out, "dataset_id: a sensitivity study runs on exactly one dataset: check one", true);
        Object.assign(body, { dataset_id: ids[0], r: Number(f.r.value), levels: Number(f.levels.value) });
      } else {
        body.dataset_ids = ids;
        if (f.n_samples.value) body.n_samples = Number(f.n_samples.value);
      }
      const resp = await postJson(path, body);
      if (!resp.ok) return say(out, await detailOf(resp), true);
      window.location.href = "/ui/studies/" + (await resp.json()).id;
    } else if (form.id === "update-form" || form.id === "predict-form") {
      ev.preventDefault();
      const what = form.id === "update-form" ? "an update" : "a prediction";
      if (!token()) return say(out, what + " needs the API token (set it above)", true);
      const f = form.elements;
      const study = Number(form.dataset.study);
      const ids = checkedIds(form, "dataset_ids");
      const path = form.dataset.post;  // the kind's create route, as the server gives it
      let body;
      if (form.id === "update-form") {
        body = { update_of: study, dataset_ids: ids };
      } else {
        body = { study_id: study, draws: Number(f.draws.value) };
        const sweep = sweepConditions(f);
        if (typeof sweep === "string") return say(out, sweep, true);
        if (sweep) body.conditions = sweep; else body.dataset_ids = ids;
      }
      if (f.name.value) body.name = f.name.value;
      const resp = await postJson(path, body);
      if (!resp.ok) return say(out, await detailOf(resp), true);
      window.location.href = "/ui/studies/" + (await resp.json()).id;
    }
  });

  document.addEventListener("htmx:configRequest", (ev) => {
    Object.assign(ev.detail.headers, authHeaders());
    const tag = ev.detail.elt && ev.detail.elt.dataset ? ev.detail.elt.dataset.etag : null;
    const trigger = ev.detail.triggeringEvent;
    if (tag && !(trigger && trigger.type === "load")) {
      ev.detail.headers["If-None-Match"] = tag;
    }
  });

  document.addEventListener("htmx:beforeSwap", (ev) => {
    const status = ev.detail.xhr.status;
    if (status === 304) {
      ev.detail.shouldSwap = false;
    } else if (status === 401 || status === 403) {
      ev.detail.shouldSwap = true;
      ev.detail.isError = false;
      ev.detail.serverResponse =
        '<p class="error needs-token" role="alert">Reading needs the API token: set it above.</p>';
    } else if (status >= 400) {
      let msg = ev.detail.xhr.statusText;
      try { msg = JSON.parse(ev.detail.xhr.responseText).detail || msg; } catch (e) { /* html */ }
      ev.detail.shouldSwap = true;
      ev.detail.isError = false;
      const p = document.createElement("p");
      p.className = "error";
      p.setAttribute("role", "alert");
      p.textContent = msg;
      ev.detail.serverResponse = p.outerHTML;
    }
  });

  /* a study that has just ended, or moved to its next stage (so one more has finished): its
     results fragment is fetched at once, not at its own next poll (up to a second later),
     and the finished stage's figures are asked for as soon as the progress shows it. The
     poll element itself is triggered ("refresh"), so the request carries its ETag and waits
     for one of its own in flight: a fragment its poll already brought is a 304, not a second
     swap that would drop the figures being fetched */
  let liveStage = null;
  document.addEventListener("htmx:afterSwap", (ev) => {
    if (!ev.detail.target || ev.detail.target.id !== "live") return;
    const live = document.getElementById("live-poll");
    const results = document.getElementById("results-poll");
    const stage = document.getElementById("progress-stage");
    const now = stage ? stage.textContent.trim() : null;
    const moved = liveStage !== null && now !== liveStage;
    liveStage = now;
    const ended = live && !live.hasAttribute("hx-get");
    if ((ended || moved) && results && results.hasAttribute("hx-get")) {
      htmx.trigger(results, "refresh");
    }
  });

  document.addEventListener("htmx:afterSettle", (ev) => { loadFigures(ev.detail.elt); showTokenState(); });
  document.addEventListener("DOMContentLoaded", () => {
    showTokenState();
    loadFigures(document);
  });
})();
