// Interactive plan viewer: a canvas, an orbit camera (drag to turn, wheel to
// zoom) and a slider / play button over the stances. No library, no network.
(function () {
  "use strict";
  var data = JSON.parse(document.getElementById("plan-data").textContent);
  var canvas = document.getElementById("view");
  var context = canvas.getContext("2d");
  var slider = document.getElementById("slider");
  var label = document.getElementById("label");
  var playButton = document.getElementById("play");
  var lo = data.bounds[0], hi = data.bounds[1];
  var target = [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2];
  var radius = Math.max(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]);
  var camera = { azimuth: -1.0, elevation: 0.35, distance: 2.2 * radius };
  var index = 0, playing = null;
  // Each robot surface's colour, from the prints of every stance (the robot's roles decide them).
  var colours = {};
  data.stances.forEach(function (stance) {
    stance.polygons.forEach(function (print) { colours[print.robot_surface] = print.colour; });
  });

  function viridis(t) {
    // Piecewise-linear approximation of matplotlib's viridis, t in [0, 1].
    var stops = [[68, 1, 84], [59, 82, 139], [33, 145, 140], [94, 201, 98], [253, 231, 37]];
    t = Math.min(1, Math.max(0, t)) * (stops.length - 1);
    var i = Math.min(stops.length - 2, Math.floor(t)), f = t - i, a = stops[i], b = stops[i + 1];
    return "rgb(" + [0, 1, 2].map(function (k) { return Math.round(a[k] + f * (b[k] - a[k])); }).join(",") + ")";
  }

  function basis() {
    var ca = Math.cos(camera.azimuth), sa = Math.sin(camera.azimuth);
    var ce = Math.cos(camera.elevation), se = Math.sin(camera.elevation);
    var back = [ce * ca, ce * sa, se];         // from the target to the eye
    var right = [-sa, ca, 0];
    var up = [-se * ca, -se * sa, ce];
    return { back: back, right: right, up: up };
  }

  function projector() {
    var b = basis(), f = 1.2 * Math.min(canvas.width, canvas.height);
    return function (p) {
      var d = [p[0] - target[0], p[1] - target[1], p[2] - target[2]];
      var x = d[0] * b.right[0] + d[1] * b.right[1] + d[2] * b.right[2];
      var y = d[0] * b.up[0] + d[1] * b.up[1] + d[2] * b.up[2];
      var z = camera.distance - (d[0] * b.back[0] + d[1] * b.back[1] + d[2] * b.back[2]);
      z = Math.max(z, 1e-3);
      return [canvas.width / 2 + f * x / z, canvas.height / 2 - f * y / z, z];
    };
  }

  function line(project, a, b, colour, width) {
    var p = project(a), q = project(b);
    context.strokeStyle = colour;
    context.lineWidth = width;
    context.beginPath();
    context.moveTo(p[0], p[1]);
    context.lineTo(q[0], q[1]);
    context.stroke();
  }

  function polygon(project, points, fill, stroke) {
    context.beginPath();
    points.forEach(function (point, i) {
      var p = project(point);
      if (i === 0) { context.moveTo(p[0], p[1]); } else { context.lineTo(p[0], p[1]); }
    });
    context.closePath();
    context.fillStyle = fill;
    context.fill();
    if (stroke) { context.strokeStyle = stroke; context.lineWidth = 0.5; context.stroke(); }
  }

  function draw() {
    var stance = data.stances[index];
    var project = projector();
    context.clearRect(0, 0, canvas.width, canvas.height);
    data.boxes.forEach(function (box) {
      box.edges.forEach(function (e) { line(project, e[0], e[1], "#999", 1); });
    });
    // Deformable surfaces, painter's algorithm: far triangles first.
    var top = Math.max(data.max_displacement, 1e-9);
    stance.deformables.forEach(function (body) {
      var faces = body.triangles.map(function (t) {
        var points = [body.vertices[t[0]], body.vertices[t[1]], body.vertices[t[2]]];
        var depth = (project(points[0])[2] + project(points[1])[2] + project(points[2])[2]) / 3;
        var value = (body.magnitude[t[0]] + body.magnitude[t[1]] + body.magnitude[t[2]]) / 3;
        return { points: points, depth: depth, value: value };
      });
      faces.sort(function (a, b) { return b.depth - a.depth; });
      faces.forEach(function (face) { var c = viridis(face.value / top); polygon(project, face.points, c, c); });
    });
    stance.polygons.forEach(function (print) {
      var colour = print.colour || "#2ca02c";
      polygon(project, print.points, colour, "#000");
    });
    stance.segments.forEach(function (s) { line(project, s[0], s[1], "#111", 2.5); });
    stance.forces.forEach(function (f) {
      var tip = [0, 1, 2].map(function (k) { return f.point[k] + data.force_scale * f.force[k]; });
      line(project, f.point, tip, "#9467bd", 2);
      var p = project(tip);
      context.fillStyle = "#9467bd";
      context.beginPath();
      context.arc(p[0], p[1], 3, 0, 2 * Math.PI);
      context.fill();
    });
    label.textContent = stance.label;
    slider.value = String(index);
    document.body.dataset.status = "ok";
  }

  function legend() {
    var parts = Object.keys(colours).map(function (name) {
      return '<span class="swatch" style="background:' + colours[name] + '"></span>' + name;
    });
    parts.push('<span class="swatch" style="background:#9467bd"></span>contact force (' +
      (data.force_legend * data.force_scale).toFixed(2) + " m = " + data.force_legend + " N)");
    parts.push('<span class="swatch" style="background:' + viridis(0) + '"></span>0 mm' +
      '<span class="swatch" style="background:' + viridis(1) + '"></span>' +
      (1000 * data.max_displacement).toFixed(1) + " mm displacement");
    document.getElementById("legend").innerHTML = data.title + ": " + parts.join(" ");
  }

  var dragging = null;
  canvas.addEventListener("mousedown", function (event) { dragging = [event.clientX, event.clientY]; });
  window.addEventListener("mouseup", function () { dragging = null; });
  window.addEventListener("mousemove", function (event) {
    if (!dragging) { return; }
    camera.azimuth -= 0.01 * (event.clientX - dragging[0]);
    camera.elevation = Math.max(-1.5, Math.min(1.5, camera.elevation + 0.01 * (event.clientY - dragging[1])));
    dragging = [event.clientX, event.clientY];
    draw();
  });
  canvas.addEventListener("wheel", function (event) {
    event.preventDefault();
    camera.distance *= event.deltaY > 0 ? 1.1 : 1 / 1.1;
    draw();
  });
  slider.max = String(data.stances.length - 1);
  slider.addEventListener("input", function () { index = Number(slider.value); draw(); });
  playButton.addEventListener("click", function () {
    if (playing !== null) { clearInterval(playing); playing = null; playButton.textContent = "Play"; return; }
    playButton.textContent = "Pause";
    playing = setInterval(function () { index = (index + 1) % data.stances.length; draw(); }, 900);
  });
  legend();
  if (data.stances.length === 0) { label.textContent = "empty plan"; document.body.dataset.status = "ok"; return; }
  draw();
})();
