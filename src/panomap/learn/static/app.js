// panomap learn: the landmark-learning page (plain JavaScript, no framework, nothing from the internet).
//
// Convention: pixel (u, v) = (column, row), the centre of the top-left pixel at (0, 0). The image is
// drawn so that pixel (u, v)'s centre is at canvas position ((u + 0.5) * scale + ox, (v + 0.5) * scale + oy)
// in CSS pixels: pixel (0, 0) covers [ox, ox + scale) x [oy, oy + scale).
//
// The server holds the state and does every computation (fit, table, previews); this page sends the
// whole state (camera, circles, landmarks, model) after each change, debounced, and shows the answer.
"use strict";

(() => {
  const $ = (id) => document.getElementById(id);
  const canvas = $("image-canvas");
  const ctx = canvas.getContext("2d");
  const magnifier = $("magnifier");
  const mctx = magnifier.getContext("2d");

  const SYNC_DELAY_MS = 250;
  const HIT_PX = 9; // how near (CSS px) a press must be to grab a landmark or handle
  const CLICK_SLOP_PX = 4; // a press that moves less than this is a click, not a pan
  const MAG_PX_PER_PIXEL = 12; // the magnifier's image pixels, CSS px each

  const state = {
    width: 0,
    height: 0,
    circles: null, // {centre: [u0, v0], cutoff_radius, outer_radius}
    detected: null,
    camera: null, // [X0, Y0, Z0] or null
    landmarks: [], // {name, u, v, X, Y, Z}; X, Y, Z null until typed
    selected: -1,
    model: "auto",
    fit: null,
    revision: 0,
    lines: null, // the camera learned from lines: {ok, message, sentences, used, rejected, azimuth_zero, ...}
    pickingAzimuth: false, // the next click on the image sets the lines' azimuth 0
  };
  const view = { scale: 1, ox: 0, oy: 0 };
  const image = new Image();
  let imageReady = false;
  let nextName = 1;

  // ------------------------------------------------------------------ transforms

  function imageToCanvas(u, v) {
    return { x: (u + 0.5) * view.scale + view.ox, y: (v + 0.5) * view.scale + view.oy };
  }
  function canvasToImage(x, y) {
    return { u: (x - view.ox) / view.scale - 0.5, v: (y - view.oy) / view.scale - 0.5 };
  }
  function imageToClient(u, v) {
    const rect = canvas.getBoundingClientRect();
    const p = imageToCanvas(u, v);
    return { x: rect.left + p.x, y: rect.top + p.y };
  }
  function clientToImage(x, y) {
    const rect = canvas.getBoundingClientRect();
    return canvasToImage(x - rect.left, y - rect.top);
  }
  function canvasSize() {
    return { w: canvas.clientWidth, h: canvas.clientHeight };
  }
  function fitView() {
    const { w, h } = canvasSize();
    if (!state.width) return;
    view.scale = Math.min(w / state.width, h / state.height);
    view.ox = (w - state.width * view.scale) / 2;
    view.oy = (h - state.height * view.scale) / 2;
    draw();
  }
  // Zoom to `scale` CSS px per image pixel, with image point (u, v) at canvas point (x, y) (default: the middle).
  function zoomTo(u, v, scale, x, y) {
    const { w, h } = canvasSize();
    view.scale = Math.min(Math.max(scale, 0.05), 64);
    const cx = x === undefined ? w / 2 : x;
    const cy = y === undefined ? h / 2 : y;
    view.ox = cx - (u + 0.5) * view.scale;
    view.oy = cy - (v + 0.5) * view.scale;
    draw();
  }
  function zoomBy(factor, x, y) {
    const { w, h } = canvasSize();
    const cx = x === undefined ? w / 2 : x;
    const cy = y === undefined ? h / 2 : y;
    const p = canvasToImage(cx, cy);
    zoomTo(p.u, p.v, view.scale * factor, cx, cy);
  }

  // ------------------------------------------------------------------ drawing

  function resizeCanvas() {
    const dpr = window.devicePixelRatio || 1;
    const { w, h } = canvasSize();
    canvas.width = Math.round(w * dpr);
    canvas.height = Math.round(h * dpr);
    ctx.setTransform(dpr, 0, 0, dpr, 0, 0);
  }

  function residualOf(name) {
    if (!state.fit || !state.fit.ok) return null;
    return state.fit.landmarks.find((row) => row.name === name) || null;
  }

  function draw() {
    const { w, h } = canvasSize();
    ctx.clearRect(0, 0, w, h);
    if (imageReady) {
      ctx.imageSmoothingEnabled = view.scale < 2;
      ctx.drawImage(image, view.ox, view.oy, state.width * view.scale, state.height * view.scale);
    }
    if (state.circles) drawCircles();
    if (state.lines && state.lines.ok && $("lines-show").checked) drawLines(state.lines);
    if (state.fit && state.fit.ok) drawFitted(state.fit);
    state.landmarks.forEach((lm, k) => drawLandmark(lm, k === state.selected));
  }

  function polyline(points) {
    ctx.beginPath();
    points.forEach((point, k) => {
      const p = imageToCanvas(point[0], point[1]);
      if (k) ctx.lineTo(p.x, p.y);
      else ctx.moveTo(p.x, p.y);
    });
    ctx.stroke();
  }

  // The camera learned from lines: each line used (green; orange where its RMS is over twice the edge noise),
  // each arc set aside (red, thin), the azimuth-0 pixel (a ring) and the horizon (dashed).
  function drawLines(lines) {
    ctx.lineWidth = 1;
    ctx.strokeStyle = "#ff3b30";
    for (const arc of lines.rejected) polyline(arc.points);
    ctx.lineWidth = 2;
    for (const line of lines.used) {
      ctx.strokeStyle = line.rms_px > 2 * lines.sigma_px ? "#ff9f1c" : "#34c759";
      for (const points of line.points) polyline(points);
    }
    if (lines.azimuth_zero) {
      const p = imageToCanvas(lines.azimuth_zero[0], lines.azimuth_zero[1]);
      ctx.strokeStyle = "#0a84ff";
      ctx.lineWidth = 2;
      ctx.beginPath();
      ctx.arc(p.x, p.y, 8, 0, 2 * Math.PI);
      ctx.stroke();
    }
    if (lines.horizon) {
      ctx.strokeStyle = "#0a84ff";
      ctx.lineWidth = 1;
      ctx.setLineDash([4, 3]);
      polyline(lines.horizon.filter((point) => point !== null));
      ctx.setLineDash([]);
    }
  }

  function drawCircles() {
    const c = state.circles;
    const p = imageToCanvas(c.centre[0], c.centre[1]);
    ctx.lineWidth = 1.5;
    for (const [r, colour] of [[c.cutoff_radius, "#ff9f1c"], [c.outer_radius, "#2ec4b6"]]) {
      if (r <= 0) continue;
      ctx.strokeStyle = colour;
      ctx.setLineDash([6, 4]);
      ctx.beginPath();
      ctx.arc(p.x, p.y, r * view.scale, 0, 2 * Math.PI);
      ctx.stroke();
    }
    ctx.setLineDash([]);
    ctx.strokeStyle = "#ff9f1c";
    ctx.beginPath();
    ctx.moveTo(p.x - 10, p.y);
    ctx.lineTo(p.x + 10, p.y);
    ctx.moveTo(p.x, p.y - 10);
    ctx.lineTo(p.x, p.y + 10);
    ctx.stroke();
  }

  // The fit's centre (a diagonal cross: where it put the optical axis, refined from the circles' centre) and
  // its horizon (world elevation 0): round the centre on a level camera, off it toward one side on a tilted one.
  function drawFitted(fit) {
    ctx.strokeStyle = "#bf5af2";
    ctx.lineWidth = 1.5;
    const c = imageToCanvas(fit.centre[0], fit.centre[1]);
    ctx.beginPath();
    ctx.moveTo(c.x - 7, c.y - 7);
    ctx.lineTo(c.x + 7, c.y + 7);
    ctx.moveTo(c.x - 7, c.y + 7);
    ctx.lineTo(c.x + 7, c.y - 7);
    ctx.stroke();
    if (!fit.horizon) return;
    const points = fit.horizon;
    ctx.setLineDash([2, 3]);
    ctx.beginPath();
    let drawing = false;
    for (const point of [...points, points[0]]) {
      if (point === null) {
        drawing = false;
        continue;
      }
      const p = imageToCanvas(point[0], point[1]);
      if (drawing) ctx.lineTo(p.x, p.y);
      else ctx.moveTo(p.x, p.y);
      drawing = true;
    }
    ctx.stroke();
    ctx.setLineDash([]);
  }

  function drawLandmark(lm, selected) {
    const p = imageToCanvas(lm.u, lm.v);
    const row = residualOf(lm.name);
    const colour = row && row.outlier ? "#ff3b30" : lm.X === null ? "#ffd60a" : "#4cd964";
    if (row) {
      // The fitted position: where the model puts the world point.
      const f = imageToCanvas(row.u_fit, row.v_fit);
      ctx.strokeStyle = "#ff3b30";
      ctx.lineWidth = 1;
      ctx.beginPath();
      ctx.moveTo(p.x, p.y);
      ctx.lineTo(f.x, f.y);
      ctx.stroke();
      ctx.beginPath();
      ctx.arc(f.x, f.y, 3, 0, 2 * Math.PI);
      ctx.stroke();
    }
    ctx.strokeStyle = "#000";
    ctx.lineWidth = 3;
    cross(p, selected ? 9 : 6);
    ctx.strokeStyle = colour;
    ctx.lineWidth = 1.5;
    cross(p, selected ? 9 : 6);
    if (selected) {
      ctx.beginPath();
      ctx.arc(p.x, p.y, 12, 0, 2 * Math.PI);
      ctx.stroke();
    }
    ctx.font = "12px system-ui, sans-serif";
    ctx.lineWidth = 3;
    ctx.strokeStyle = "#000";
    ctx.strokeText(lm.name, p.x + 8, p.y - 8);
    ctx.fillStyle = colour;
    ctx.fillText(lm.name, p.x + 8, p.y - 8);
  }

  function cross(p, size) {
    ctx.beginPath();
    ctx.moveTo(p.x - size, p.y);
    ctx.lineTo(p.x + size, p.y);
    ctx.moveTo(p.x, p.y - size);
    ctx.lineTo(p.x, p.y + size);
    ctx.stroke();
  }

  // The magnifier: image pixels around (u, v), MAG_PX_PER_PIXEL each, a cross at (u, v) exactly.
  function drawMagnifier(u, v) {
    if (!imageReady) return;
    const size = magnifier.width;
    const span = size / MAG_PX_PER_PIXEL; // image pixels across
    // Source rectangle in image-file coordinates: pixel (u, v)'s centre is at (u + 0.5, v + 0.5).
    const sx = u + 0.5 - span / 2;
    const sy = v + 0.5 - span / 2;
    mctx.imageSmoothingEnabled = false;
    mctx.fillStyle = "#000";
    mctx.fillRect(0, 0, size, size);
    mctx.drawImage(image, sx, sy, span, span, 0, 0, size, size);
    mctx.strokeStyle = "#ff3b30";
    mctx.lineWidth = 1;
    mctx.beginPath();
    mctx.moveTo(size / 2, 0);
    mctx.lineTo(size / 2, size);
    mctx.moveTo(0, size / 2);
    mctx.lineTo(size, size / 2);
    mctx.stroke();
    magnifier.style.display = "block";
  }

  // ------------------------------------------------------------------ pointer

  let drag = null; // {kind: "pan" | "landmark" | "centre" | "cutoff" | "outer", ...}

  function hitTest(x, y) {
    for (let k = state.landmarks.length - 1; k >= 0; k--) {
      const p = imageToCanvas(state.landmarks[k].u, state.landmarks[k].v);
      if (Math.hypot(p.x - x, p.y - y) <= HIT_PX) return { kind: "landmark", index: k, dx: p.x - x, dy: p.y - y };
    }
    if (state.circles) {
      const c = imageToCanvas(state.circles.centre[0], state.circles.centre[1]);
      const d = Math.hypot(c.x - x, c.y - y);
      if (d <= HIT_PX) return { kind: "centre", dx: c.x - x, dy: c.y - y };
      for (const kind of ["cutoff", "outer"]) {
        const r = state.circles[kind + "_radius"] * view.scale;
        if (r > 0 && Math.abs(d - r) <= HIT_PX / 1.5) return { kind };
      }
    }
    return null;
  }

  function localPoint(event) {
    const rect = canvas.getBoundingClientRect();
    return { x: event.clientX - rect.left, y: event.clientY - rect.top };
  }

  canvas.addEventListener("pointerdown", (event) => {
    if (event.button !== 0 && event.button !== 1) return;
    canvas.focus();
    const p = localPoint(event);
    const hit = event.button === 0 ? hitTest(p.x, p.y) : null;
    drag = hit || { kind: "pan" };
    drag.start = p;
    drag.view = { ox: view.ox, oy: view.oy };
    drag.moved = false;
    if (hit && hit.kind === "landmark") select(hit.index);
    canvas.setPointerCapture(event.pointerId);
  });

  canvas.addEventListener("pointermove", (event) => {
    const p = localPoint(event);
    const at = canvasToImage(p.x, p.y);
    $("cursor-pos").textContent = `u ${at.u.toFixed(2)}, v ${at.v.toFixed(2)}`;
    if (!drag) {
      drawMagnifier(at.u, at.v);
      return;
    }
    if (Math.hypot(p.x - drag.start.x, p.y - drag.start.y) >= CLICK_SLOP_PX) drag.moved = true;
    if (!drag.moved) return;
    if (drag.kind === "pan") {
      view.ox = drag.view.ox + p.x - drag.start.x;
      view.oy = drag.view.oy + p.y - drag.start.y;
    } else if (drag.kind === "landmark") {
      const q = canvasToImage(p.x + drag.dx, p.y + drag.dy);
      setLandmarkPixel(drag.index, q.u, q.v);
      drawMagnifier(q.u, q.v);
    } else if (drag.kind === "centre") {
      const q = canvasToImage(p.x + drag.dx, p.y + drag.dy);
      state.circles.centre = [round3(q.u), round3(q.v)];
      showCircles();
    } else {
      const c = imageToCanvas(state.circles.centre[0], state.circles.centre[1]);
      state.circles[drag.kind + "_radius"] = round3(Math.hypot(p.x - c.x, p.y - c.y) / view.scale);
      showCircles();
    }
    draw();
  });

  function endDrag(event) {
    if (!drag) return;
    const finished = drag;
    drag = null;
    if (finished.kind === "pan" && !finished.moved && event.type === "pointerup" && event.button === 0) {
      const q = canvasToImage(finished.start.x, finished.start.y);
      if (state.pickingAzimuth) setLinesAzimuth(q.u, q.v);
      else addLandmark(q.u, q.v);
    } else if (finished.moved && finished.kind !== "pan") {
      scheduleSync();
    }
    draw();
  }
  canvas.addEventListener("pointerup", endDrag);
  canvas.addEventListener("pointercancel", endDrag);
  canvas.addEventListener("pointerleave", () => {
    if (!drag) magnifier.style.display = "none";
  });
  canvas.addEventListener(
    "wheel",
    (event) => {
      event.preventDefault();
      const p = localPoint(event);
      zoomBy(event.deltaY < 0 ? 1.25 : 0.8, p.x, p.y);
    },
    { passive: false },
  );
  canvas.addEventListener("keydown", (event) => {
    if (state.selected < 0) return;
    const step = event.shiftKey ? 1 : 0.1;
    const lm = state.landmarks[state.selected];
    const moves = { ArrowLeft: [-step, 0], ArrowRight: [step, 0], ArrowUp: [0, -step], ArrowDown: [0, step] };
    if (event.key in moves) {
      event.preventDefault();
      const [du, dv] = moves[event.key];
      setLandmarkPixel(state.selected, lm.u + du, lm.v + dv);
      draw();
      scheduleSync();
    } else if (event.key === "Delete" || event.key === "Backspace") {
      event.preventDefault();
      deleteSelected();
    }
  });
  $("zoom-in").addEventListener("click", () => zoomBy(1.5));
  $("zoom-out").addEventListener("click", () => zoomBy(1 / 1.5));
  $("zoom-fit").addEventListener("click", fitView);
  window.addEventListener("resize", () => {
    resizeCanvas();
    draw();
  });

  // ------------------------------------------------------------------ landmarks

  function round3(x) {
    return Math.round(x * 1000) / 1000;
  }
  function clampU(u) {
    return Math.min(Math.max(u, -0.5), state.width - 0.5);
  }
  function clampV(v) {
    return Math.min(Math.max(v, -0.5), state.height - 0.5);
  }
  function setLandmarkPixel(k, u, v) {
    state.landmarks[k].u = round3(clampU(u));
    state.landmarks[k].v = round3(clampV(v));
    if (k === state.selected) showSelected();
    renderTable();
  }

  function freshName() {
    const taken = new Set(state.landmarks.map((lm) => lm.name));
    while (taken.has(`L${nextName}`)) nextName++;
    return `L${nextName}`;
  }

  function addLandmark(u, v) {
    if (u < -0.5 || v < -0.5 || u > state.width - 0.5 || v > state.height - 0.5) {
      showMessage("that is outside the image", true);
      return;
    }
    state.landmarks.push({ name: freshName(), u: round3(u), v: round3(v), X: null, Y: null, Z: null });
    select(state.landmarks.length - 1);
    renderTable();
    draw();
    scheduleSync();
    $("lm-x").focus();
  }

  function deleteSelected() {
    if (state.selected < 0) return;
    state.landmarks.splice(state.selected, 1);
    select(-1);
    renderTable();
    draw();
    scheduleSync();
  }

  function select(k) {
    state.selected = k;
    showSelected();
    renderTable();
  }

  function numberText(x) {
    return x === null || x === undefined ? "" : String(x);
  }

  function showSelected() {
    const lm = state.landmarks[state.selected];
    $("landmark-panel").disabled = !lm;
    $("lm-name").value = lm ? lm.name : "";
    $("lm-u").value = lm ? numberText(lm.u) : "";
    $("lm-v").value = lm ? numberText(lm.v) : "";
    $("lm-x").value = lm ? numberText(lm.X) : "";
    $("lm-y").value = lm ? numberText(lm.Y) : "";
    $("lm-z").value = lm ? numberText(lm.Z) : "";
  }

  function readNumber(id) {
    const text = $(id).value.trim();
    if (text === "") return null;
    const x = Number(text);
    return Number.isFinite(x) ? x : NaN;
  }

  // The form edits the selected landmark: name, precise pixel, world point.
  function formChanged(event) {
    const lm = state.landmarks[state.selected];
    if (!lm) return;
    const before = JSON.stringify(lm);
    const name = $("lm-name").value.trim();
    if (name) lm.name = name;
    const u = readNumber("lm-u");
    const v = readNumber("lm-v");
    if (u !== null && !Number.isNaN(u)) lm.u = u;
    if (v !== null && !Number.isNaN(v)) lm.v = v;
    const world = ["lm-x", "lm-y", "lm-z"].map(readNumber);
    if (world.some(Number.isNaN)) {
      showMessage("X, Y and Z must be numbers", true);
      return;
    }
    if (world.every((c) => c !== null)) {
      [lm.X, lm.Y, lm.Z] = world;
    } else if (world.every((c) => c === null)) {
      lm.X = lm.Y = lm.Z = null;
    } else if (event && event.type === "change") {
      // Wait for all three before sending a world point.
      return;
    }
    if (JSON.stringify(lm) === before) return; // e.g. the change event when leaving a field
    renderTable();
    draw();
    scheduleSync();
  }
  for (const id of ["lm-name", "lm-u", "lm-v", "lm-x", "lm-y", "lm-z"]) {
    $(id).addEventListener("input", formChanged);
    $(id).addEventListener("change", formChanged);
  }
  $("lm-delete").addEventListener("click", deleteSelected);

  function fixed(x, digits) {
    return x === null || x === undefined ? "" : Number(x).toFixed(digits);
  }

  function renderTable() {
    const body = $("landmark-table").querySelector("tbody");
    body.replaceChildren();
    state.landmarks.forEach((lm, k) => {
      const row = residualOf(lm.name);
      const tr = document.createElement("tr");
      tr.dataset.name = lm.name;
      if (k === state.selected) tr.classList.add("selected");
      if (row && row.outlier) tr.classList.add("outlier");
      if (lm.X === null) tr.classList.add("incomplete");
      const cells = [lm.name, fixed(lm.u, 2), fixed(lm.v, 2), fixed(lm.X, 3), fixed(lm.Y, 3), fixed(lm.Z, 3)];
      for (const text of cells) {
        const td = document.createElement("td");
        td.textContent = text;
        tr.append(td);
      }
      const td = document.createElement("td");
      td.className = "residual";
      if (row) {
        td.textContent = row.residual_px.toFixed(3) + (row.outlier ? " OUTLIER" : "");
        td.dataset.residual = String(row.residual_px);
        td.title = row.outlier ? "dropped as an outlier: it disagrees with the rest" : "distance to the fitted pixel";
      } else {
        td.textContent = lm.X === null ? "needs X,Y,Z" : "-";
      }
      tr.append(td);
      // pointerdown, not click: leaving a form field re-renders the table before a click would complete.
      tr.addEventListener("pointerdown", () => {
        select(k);
        const p = imageToCanvas(lm.u, lm.v);
        const { w, h } = canvasSize();
        if (p.x < 0 || p.y < 0 || p.x > w || p.y > h) zoomTo(lm.u, lm.v, view.scale);
        draw();
      });
      body.append(tr);
    });
  }

  // ------------------------------------------------------------------ camera and circles

  function showCamera() {
    const c = state.camera || [null, null, null];
    $("cam-x").value = numberText(c[0]);
    $("cam-y").value = numberText(c[1]);
    $("cam-z").value = numberText(c[2]);
  }
  function cameraChanged() {
    const c = ["cam-x", "cam-y", "cam-z"].map(readNumber);
    if (c.some(Number.isNaN)) return showMessage("the camera position must be numbers", true);
    state.camera = c.every((x) => x !== null) ? c : null;
    scheduleSync();
  }
  for (const id of ["cam-x", "cam-y", "cam-z"]) $(id).addEventListener("input", cameraChanged);

  function showCircles() {
    const c = state.circles;
    $("centre-u").value = numberText(c.centre[0]);
    $("centre-v").value = numberText(c.centre[1]);
    $("cutoff-r").value = numberText(c.cutoff_radius);
    $("outer-r").value = numberText(c.outer_radius);
  }
  function circlesChanged() {
    const [u, v, r, R] = ["centre-u", "centre-v", "cutoff-r", "outer-r"].map(readNumber);
    if ([u, v, r, R].some((x) => x === null || Number.isNaN(x))) return;
    state.circles = { centre: [u, v], cutoff_radius: r, outer_radius: R };
    draw();
    scheduleSync();
  }
  for (const id of ["centre-u", "centre-v", "cutoff-r", "outer-r"]) $(id).addEventListener("input", circlesChanged);
  $("reset-circles").addEventListener("click", () => {
    if (!state.detected) return showMessage("no circles were detected in this image", true);
    state.circles = {
      centre: state.detected.centre.slice(),
      cutoff_radius: state.detected.cutoff_radius || 0,
      outer_radius: state.detected.outer_radius,
    };
    showCircles();
    draw();
    scheduleSync();
  });
  $("model").addEventListener("change", () => {
    state.model = $("model").value;
    scheduleSync();
  });

  // ------------------------------------------------------------------ server

  function showMessage(text, isError) {
    const m = $("message");
    m.textContent = text;
    m.className = isError ? "error" : "ok";
  }

  async function api(method, path, body) {
    const options = { method, headers: {} };
    if (body !== undefined) {
      options.headers["Content-Type"] = "application/json";
      options.body = JSON.stringify(body);
    }
    const response = await fetch(path, options);
    const data = await response.json();
    if (!response.ok) {
      const error = new Error(data.error || `${response.status} ${response.statusText}`);
      error.status = response.status;
      error.data = data;
      throw error;
    }
    return data;
  }

  let syncTimer = null; // a change waiting to be sent
  let syncing = null; // the request loop in flight
  let syncAgain = false; // a change arrived while a request was in flight

  // data-synced on <body> is "yes" when the server has seen every change (tests wait for it).
  function markSynced() {
    document.body.dataset.synced = syncTimer || syncing ? "no" : "yes";
  }

  function scheduleSync() {
    clearTimeout(syncTimer);
    syncTimer = setTimeout(() => {
      syncTimer = null;
      sync();
    }, SYNC_DELAY_MS);
    markSynced();
  }

  function payload() {
    return {
      camera: state.camera,
      circles: state.circles,
      model: state.model,
      landmarks: state.landmarks.map(({ name, u, v, X, Y, Z }) => ({ name, u, v, X, Y, Z })),
    };
  }

  // Send the state now; one request at a time, the latest state always sent last. Resolves when in step.
  async function sync() {
    if (syncTimer) {
      clearTimeout(syncTimer);
      syncTimer = null;
    }
    if (syncing) {
      syncAgain = true;
      return syncing;
    }
    syncing = (async () => {
      do {
        syncAgain = false;
        try {
          const answer = await api("POST", "/api/state", payload());
          showFit(answer.fit);
          showMessage("", false);
        } catch (error) {
          showMessage(error.message, true);
        }
      } while (syncAgain);
    })();
    markSynced();
    try {
      await syncing;
    } finally {
      syncing = null;
      markSynced();
    }
    return undefined;
  }

  function showFit(fit) {
    state.fit = fit;
    state.revision = fit.revision;
    const status = $("fit-status");
    status.textContent = fit.message;
    status.className = fit.ok ? "ok" : fit.need > 0 ? "waiting" : "failed";
    const warnings = $("fit-warnings");
    warnings.replaceChildren(
      ...[...(fit.warnings || []), ...(fit.diagnosis || []).map((text) => `diagnosis: ${text}`)].map((text) => {
        const li = document.createElement("li");
        li.textContent = text;
        return li;
      }),
    );
    const pano = $("panorama");
    if (fit.ok) {
      pano.src = `/api/panorama.png?rev=${fit.revision}`;
      pano.hidden = false;
    } else {
      pano.hidden = true;
      pano.removeAttribute("src");
    }
    document.body.dataset.fitRevision = String(fit.revision);
    renderTable();
    drawCurve(fit.ok ? fit.curve : null);
    draw();
  }

  // Fig. 7b: f_r with its +-2 standard error band, the landmarks (+), the cut-off and outer radii.
  function drawCurve(curve) {
    const c = $("curve");
    const g = c.getContext("2d");
    const W = c.width;
    const H = c.height;
    g.clearRect(0, 0, W, H);
    g.fillStyle = "#fff";
    g.fillRect(0, 0, W, H);
    if (!curve) {
      g.fillStyle = "#888";
      g.font = "13px system-ui, sans-serif";
      g.fillText("the fitted curve r = f(rho) appears here", 20, H / 2);
      return;
    }
    const left = 46;
    const right = 10;
    const top = 10;
    const bottom = 34;
    const xs = curve.elevation_deg.concat(curve.landmarks.map((l) => l.elevation_deg));
    const ys = curve.radius_px
      .map((r, k) => r + 2 * curve.se_px[k])
      .concat(curve.landmarks.map((l) => l.radius_px), [curve.outer_radius_px]);
    const x0 = Math.min(...xs);
    const x1 = Math.max(...xs);
    const y1 = Math.max(...ys) * 1.04;
    const X = (x) => left + ((x - x0) / (x1 - x0 || 1)) * (W - left - right);
    const Y = (y) => H - bottom - (y / (y1 || 1)) * (H - top - bottom);
    g.strokeStyle = "#ddd";
    g.fillStyle = "#444";
    g.font = "11px system-ui, sans-serif";
    g.lineWidth = 1;
    for (const t of ticks(x0, x1, 6)) {
      g.beginPath();
      g.moveTo(X(t), top);
      g.lineTo(X(t), H - bottom);
      g.stroke();
      g.fillText(String(t), X(t) - 8, H - bottom + 14);
    }
    for (const t of ticks(0, y1, 5)) {
      g.beginPath();
      g.moveTo(left, Y(t));
      g.lineTo(W - right, Y(t));
      g.stroke();
      g.fillText(String(t), 4, Y(t) + 4);
    }
    g.fillText("elevation rho (deg)", W / 2 - 40, H - 4);
    g.fillText("r (px)", left + 4, top + 10);
    // the band
    g.fillStyle = "rgba(31, 119, 180, 0.25)";
    g.beginPath();
    curve.elevation_deg.forEach((e, k) => {
      const y = Y(curve.radius_px[k] + 2 * curve.se_px[k]);
      if (k === 0) g.moveTo(X(e), y);
      else g.lineTo(X(e), y);
    });
    for (let k = curve.elevation_deg.length - 1; k >= 0; k--) {
      g.lineTo(X(curve.elevation_deg[k]), Y(curve.radius_px[k] - 2 * curve.se_px[k]));
    }
    g.closePath();
    g.fill();
    // the curve
    g.strokeStyle = "#1f77b4";
    g.lineWidth = 2;
    g.beginPath();
    curve.elevation_deg.forEach((e, k) => {
      if (k === 0) g.moveTo(X(e), Y(curve.radius_px[k]));
      else g.lineTo(X(e), Y(curve.radius_px[k]));
    });
    g.stroke();
    // cut-off and outer radii
    g.strokeStyle = "#888";
    g.lineWidth = 1;
    g.setLineDash([3, 3]);
    for (const r of [curve.cutoff_radius_px, curve.outer_radius_px]) {
      g.beginPath();
      g.moveTo(left, Y(r));
      g.lineTo(W - right, Y(r));
      g.stroke();
    }
    g.setLineDash([]);
    // landmarks
    g.lineWidth = 2;
    for (const l of curve.landmarks) {
      const x = X(l.elevation_deg);
      const y = Y(l.radius_px);
      g.beginPath();
      if (l.outlier) {
        // An outlier: an orange x (not used by the fit).
        g.strokeStyle = "#ff7f0e";
        g.moveTo(x - 4, y - 4);
        g.lineTo(x + 4, y + 4);
        g.moveTo(x - 4, y + 4);
        g.lineTo(x + 4, y - 4);
      } else {
        g.strokeStyle = "#d62728";
        g.moveTo(x - 5, y);
        g.lineTo(x + 5, y);
        g.moveTo(x, y - 5);
        g.lineTo(x, y + 5);
      }
      g.stroke();
    }
    g.fillStyle = "#1f77b4";
    g.fillText("f_r with +-2 standard errors; + landmarks, x outliers", left + 4, top + 24);
  }

  function ticks(lo, hi, count) {
    const span = hi - lo || 1;
    const raw = span / count;
    const mag = 10 ** Math.floor(Math.log10(raw));
    const step = [1, 2, 5, 10].map((m) => m * mag).find((s) => s >= raw);
    const out = [];
    for (let t = Math.ceil(lo / step) * step; t <= hi + 1e-9; t += step) out.push(Math.round(t * 1e6) / 1e6);
    return out;
  }

  // ------------------------------------------------------------------ files

  async function refreshFiles() {
    try {
      const files = await api("GET", "/api/files");
      $("landmark-files").replaceChildren(
        ...files.landmarks.map((name) => {
          const option = document.createElement("option");
          option.value = name;
          return option;
        }),
      );
    } catch (error) {
      showMessage(error.message, true);
    }
  }

  // A save onto an existing file is refused (409, "exists"); ask, and resend with overwrite if the user agrees.
  async function postFile(path, name) {
    try {
      return await api("POST", path, { name });
    } catch (error) {
      const exists = error.status === 409 && error.data && error.data.exists;
      if (!exists || !window.confirm(`${exists} already exists in the folder. Replace it?`)) throw error;
      return api("POST", path, { name, overwrite: true });
    }
  }

  async function fileAction(path, inputId, after) {
    await sync();
    const status = $("files-status");
    try {
      const name = $(inputId).value.trim();
      const answer = path.endsWith("/save") ? await postFile(path, name) : await api("POST", path, { name });
      status.textContent = answer.wrote ? `wrote ${answer.wrote}` : `loaded ${$(inputId).value.trim()}`;
      status.dataset.done = answer.wrote || "loaded";
      showMessage(status.textContent, false);
      if (after) after(answer);
      refreshFiles();
    } catch (error) {
      status.textContent = error.message;
      status.dataset.done = "error";
      showMessage(error.message, true);
    }
  }
  $("save-landmarks").addEventListener("click", () => fileAction("/api/landmarks/save", "landmarks-file"));
  $("save-table").addEventListener("click", () => fileAction("/api/table/save", "table-file"));
  $("load-landmarks").addEventListener("click", () => fileAction("/api/landmarks/load", "landmarks-file", applyState));

  // ------------------------------------------------------------------ learning from lines

  function showLines(lines) {
    state.lines = lines && lines.revision ? lines : null;
    const status = $("lines-status");
    const learned = Boolean(state.lines && state.lines.ok);
    if (state.lines) {
      status.textContent = state.lines.message;
      status.className = learned ? "note" : "note failed";
      status.dataset.revision = String(state.lines.revision);
    }
    $("lines-report").replaceChildren(
      ...(learned ? state.lines.sentences : []).map((text) => {
        const li = document.createElement("li");
        li.textContent = text;
        return li;
      }),
    );
    $("lines-azimuth").disabled = !learned;
    $("save-lines-table").disabled = !learned;
    draw();
  }

  function pickAzimuth(on) {
    state.pickingAzimuth = on;
    canvas.classList.toggle("picking", on);
    $("lines-azimuth").textContent = on ? "click the image (Esc: cancel)" : "set azimuth 0 by a click";
  }

  async function learnLines() {
    const button = $("learn-lines");
    button.disabled = true;
    $("lines-status").textContent = "learning from lines...";
    try {
      const s = await api("POST", "/api/lines", {});
      showLines(s.lines);
      showMessage(s.lines.message, !s.lines.ok);
    } catch (error) {
      showMessage(error.message, true);
    } finally {
      button.disabled = false;
    }
  }

  async function setLinesAzimuth(u, v) {
    pickAzimuth(false);
    try {
      const s = await api("POST", "/api/lines/azimuth", { u: round3(u), v: round3(v) });
      showLines(s.lines);
      showMessage(`azimuth 0 set at (${u.toFixed(1)}, ${v.toFixed(1)})`, false);
    } catch (error) {
      showMessage(error.message, true);
    }
  }

  $("learn-lines").addEventListener("click", learnLines);
  $("lines-azimuth").addEventListener("click", () => pickAzimuth(!state.pickingAzimuth));
  $("lines-show").addEventListener("change", draw);
  $("save-lines-table").addEventListener("click", () => fileAction("/api/lines/save", "lines-file"));
  window.addEventListener("keydown", (event) => {
    if (event.key === "Escape" && state.pickingAzimuth) pickAzimuth(false);
  });

  // ------------------------------------------------------------------ start

  function applyState(s) {
    state.width = s.image.width;
    state.height = s.image.height;
    state.circles = { centre: s.circles.centre, cutoff_radius: s.circles.cutoff_radius, outer_radius: s.circles.outer_radius };
    state.detected = s.circles.detected;
    state.camera = s.camera;
    state.landmarks = s.landmarks;
    state.model = s.model;
    select(-1);
    showCamera();
    showCircles();
    $("circles-note").textContent = s.circles.note || "";
    showFit(s.fit);
    showLines(s.lines);
  }

  async function start() {
    resizeCanvas();
    try {
      const s = await api("GET", "/api/state");
      $("image-name").textContent = `${s.image.name} (${s.image.width} x ${s.image.height}); files in ${s.folder}`;
      $("model").replaceChildren(
        ...s.models.map((name) => {
          const option = document.createElement("option");
          option.value = name;
          option.textContent = name === "auto" ? "auto (leave-one-out)" : name;
          return option;
        }),
      );
      applyState(s);
      $("model").value = s.model;
      await new Promise((resolve, reject) => {
        image.onload = resolve;
        image.onerror = () => reject(new Error("cannot load the image"));
        image.src = "/api/image";
      });
      imageReady = true;
      fitView();
      refreshFiles();
      document.body.dataset.ready = "yes";
      markSynced();
    } catch (error) {
      showMessage(error.message, true);
    }
  }

  // For tests and scripts: the page's own transform and a few controls.
  window.panomap = {
    imageToClient,
    clientToImage,
    zoomTo,
    fitView,
    sync,
    view,
    state,
  };

  start();
})();
