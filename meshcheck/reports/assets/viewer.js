// meshcheck HTML report: builds the header, the findings table and the 3D view from the JSON
// in #meshcheck-data and the geometry in #meshcheck-geometry. Everything in the data came from
// the user's files: it is only ever put into the page with textContent, never parsed as HTML.
(function () {
  "use strict";
  const T = window.MeshcheckThree;
  const STATUS_COLORS = {
    duplicate: 0xd00060,
    interference: 0xff8c00,
    clearance: 0xc026d3,
    touching: 0x2f7de1,
    approved: 0x1f9d55,
  };
  const PART_COLOR = 0x9aa0a6;
  const CLASH_COLOR = 0xe00000;
  const STATUS_ORDER = ["duplicate", "interference", "clearance", "touching"];

  // Control characters, bidirectional overrides and the like would hide or reorder text: show
  // them as escapes so a hostile name reads as what it is.
  const UNPRINTABLE = /[\u0000-\u001f\u007f-\u009f\u200b-\u200f\u2028\u2029\u202a-\u202e\u2060-\u206f\ufeff]/g;
  function visible(value) {
    return String(value).replace(
      UNPRINTABLE,
      (c) => "\\u" + c.charCodeAt(0).toString(16).padStart(4, "0"),
    );
  }

  function el(tag, className, text) {
    const node = document.createElement(tag);
    if (className) node.className = className;
    if (text !== undefined && text !== null) node.textContent = visible(text);
    return node;
  }

  function fmt(x) {
    if (x === null || x === undefined) return "\u2014";
    if (x === 0) return "0";
    return String(Number(x.toPrecision(6)));
  }

  async function decodeGeometry(text) {
    const bin = atob(text.trim());
    const bytes = new Uint8Array(bin.length);
    for (let i = 0; i < bin.length; i++) bytes[i] = bin.charCodeAt(i);
    const stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream("gzip"));
    return await new Response(stream).arrayBuffer();
  }

  function buildGeometry(buffer, m) {
    const g = new T.BufferGeometry();
    g.setAttribute("position", new T.BufferAttribute(new Int16Array(buffer, m.pos, m.nv * 3), 3));
    const Index = m.wide ? Uint32Array : Uint16Array;
    g.setIndex(new T.BufferAttribute(new Index(buffer, m.idx, m.nf * 3), 1));
    g.computeBoundingBox();
    g.computeBoundingSphere();
    return g;
  }

  function matrixOf(values) {
    const m = new T.Matrix4();
    m.fromArray(values); // column-major
    return m;
  }

  // ------------------------------------------------------------------------------ header

  function buildHeader(data) {
    const s = data.summary;
    const header = document.getElementById("header");
    const verdict = el("span", "verdict " + (s.passed ? "pass" : "fail"), s.passed ? "PASS" : "FAIL");
    verdict.id = "verdict";
    const title = el("h1", null, "meshcheck report");
    title.prepend(verdict, " ");
    header.append(title);

    const counts = el("p", "counts");
    counts.id = "counts";
    const items = [
      [s.parts, "parts"],
      [s.pairs_checked, "pairs checked"],
      [s.duplicate, "duplicate"],
      [s.interference, "interference"],
      [s.touching, "touching"],
      [s.clearance, "clearance"],
      [s.approved, "approved"],
      [s.failed, "failing the run"],
    ];
    items.forEach(([n, label], k) => {
      if (k) counts.append(" \u00b7 ");
      counts.append(el("b", null, n), " " + label);
    });
    header.append(counts);

    const u = data.units;
    const settings = el("p", "settings");
    const pairs = [
      ["tolerance", fmt(s.tolerance) + " " + u],
      ["clearance", s.required_clearance === null ? "not set" : fmt(s.required_clearance) + " " + u],
      ["units", u],
      ["fail on", s.fail_on.length ? s.fail_on.join(", ") : "nothing"],
      ["meshcheck", data.version],
    ];
    const tri = data.triangles;
    if (tri.shown < tri.parts) {
      pairs.push(["view simplified to", tri.shown.toLocaleString("en") + " of " + tri.parts.toLocaleString("en") + " triangles"]);
    }
    pairs.forEach(([k, v], i) => {
      if (i) settings.append(" \u00b7 ");
      settings.append(k + " ", el("b", null, v));
    });
    header.append(settings);

    const inputs = el("details", "inputs");
    inputs.append(el("summary", null, data.inputs.length + " input" + (data.inputs.length === 1 ? "" : "s")));
    const list = el("ul");
    for (const name of data.inputs) list.append(el("li", null, name));
    inputs.append(list);
    header.append(inputs);

    if (s.warnings.length) {
      const warn = el("details", "warnings");
      warn.append(el("summary", null, s.warnings.length + " warning" + (s.warnings.length === 1 ? "" : "s")));
      const wl = el("ul");
      for (const w of s.warnings) wl.append(el("li", null, w));
      warn.append(wl);
      header.append(warn);
    }
  }

  // ------------------------------------------------------------------------------ 3D view

  function createView(data, buffer) {
    const container = document.getElementById("view");
    const renderer = new T.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
    renderer.setPixelRatio(window.devicePixelRatio || 1);
    renderer.setClearColor(0xf4f5f7, 1);
    container.append(renderer.domElement);

    const scene = new T.Scene();
    const camera = new T.PerspectiveCamera(40, 1, 1, 10);
    scene.add(new T.HemisphereLight(0xffffff, 0x8a8f98, 1.6));
    const headlight = new T.DirectionalLight(0xffffff, 1.4);
    headlight.position.set(0.4, 0.6, 1);
    camera.add(headlight);
    scene.add(camera);

    const material = (color, opacity) =>
      new T.MeshStandardMaterial({
        color,
        roughness: 0.75,
        metalness: 0.0,
        flatShading: true,
        side: T.DoubleSide,
        transparent: opacity < 1,
        opacity,
        depthWrite: true, // with back-to-front sorting: a part on top of a larger one stays on top
      });
    const partMaterial = material(PART_COLOR, 0.18);
    const statusMaterials = {};
    for (const [status, color] of Object.entries(STATUS_COLORS)) {
      statusMaterials[status] = material(color, 0.3);
    }
    const edgeMaterial = new T.LineBasicMaterial({ color: 0x30343a, transparent: true, opacity: 0.28 });
    const clashMaterial = material(CLASH_COLOR, 1.0);

    const geometries = data.meshes.map((m) => buildGeometry(buffer, m));
    const edges = [];
    const edgesOf = (k) => (edges[k] ||= new T.EdgesGeometry(geometries[k], 35));

    const parts = new T.Group();
    const partObjects = new Map();
    const sceneBox = new T.Box3();
    for (const part of data.parts) {
      if (part.mesh === null) continue;
      const m = matrixOf(part.matrix);
      const base = part.status ? statusMaterials[part.status] : partMaterial;
      const mesh = new T.Mesh(geometries[part.mesh], base);
      mesh.matrixAutoUpdate = false;
      mesh.matrix.copy(m);
      mesh.renderOrder = 1;
      const lines = new T.LineSegments(edgesOf(part.mesh), edgeMaterial);
      lines.matrixAutoUpdate = false;
      lines.matrix.copy(m);
      lines.renderOrder = 2;
      parts.add(mesh, lines);
      const box = geometries[part.mesh].boundingBox.clone().applyMatrix4(m);
      sceneBox.union(box);
      partObjects.set(part.name, { mesh, box });
    }
    scene.add(parts);

    const markers = new Map(); // finding id -> objects drawn for it
    for (const f of data.findings) {
      const objects = [];
      if (f.solid !== null) {
        const solid = new T.Mesh(geometries[f.solid], clashMaterial);
        solid.matrixAutoUpdate = false;
        solid.matrix.copy(matrixOf(data.meshes[f.solid].matrix));
        objects.push(solid);
      }
      if (f.line !== null) {
        // The closest points and the segment between them, drawn over everything (transparent
        // objects are drawn last, in renderOrder), so the parts around them cannot hide them.
        const g = new T.BufferGeometry();
        g.setAttribute("position", new T.Float32BufferAttribute(f.line.flat(), 3));
        const color = f.approved !== null ? STATUS_COLORS.approved : STATUS_COLORS[f.status];
        const over = { color, depthTest: false, transparent: true };
        objects.push(new T.LineSegments(g, new T.LineBasicMaterial(over)));
        objects.push(new T.Points(g, new T.PointsMaterial({ ...over, size: 7, sizeAttenuation: false })));
      }
      for (const o of objects) {
        o.renderOrder = 3;
        scene.add(o);
      }
      markers.set(f.id, objects);
    }

    if (sceneBox.isEmpty()) sceneBox.set(new T.Vector3(-1, -1, -1), new T.Vector3(1, 1, 1));
    const sceneSphere = sceneBox.getBoundingSphere(new T.Sphere());
    const radius = Math.max(sceneSphere.radius, 1e-9);
    camera.near = radius / 2000;
    camera.far = radius * 200;
    camera.updateProjectionMatrix();

    const controls = new T.OrbitControls(camera, renderer.domElement);
    controls.enableDamping = false;
    controls.screenSpacePanning = true;

    let pending = false;
    const render = () => {
      pending = false;
      renderer.render(scene, camera);
    };
    const requestRender = () => {
      if (!pending) {
        pending = true;
        requestAnimationFrame(render);
      }
    };
    controls.addEventListener("change", requestRender);

    function resize() {
      const w = Math.max(container.clientWidth, 1);
      const h = Math.max(container.clientHeight, 1);
      renderer.setSize(w, h, false);
      renderer.domElement.style.width = "100%";
      renderer.domElement.style.height = "100%";
      camera.aspect = w / h;
      camera.updateProjectionMatrix();
    }
    window.addEventListener("resize", () => {
      resize();
      requestRender();
    });

    // Look at a sphere along the current viewing direction (or the default one).
    function lookAt(centre, r, direction) {
      const dir = direction || camera.position.clone().sub(controls.target);
      if (dir.lengthSq() === 0) dir.set(1, -1.2, 0.9);
      dir.normalize();
      const fov = (camera.fov * Math.PI) / 180;
      const distance = (1.6 * r) / Math.sin(Math.min(fov, fov * camera.aspect) / 2);
      controls.target.copy(centre);
      camera.position.copy(centre).addScaledVector(dir, distance);
      camera.up.set(0, 0, 1);
      controls.update();
      render();
    }

    function home() {
      lookAt(sceneSphere.center, 0.8 * radius, new T.Vector3(1, -1.2, 0.9));
    }

    function frame(finding) {
      const selected = [finding.a, finding.b].filter((n) => partObjects.has(n));
      const box = new T.Box3();
      if (finding.box) {
        box.set(new T.Vector3(...finding.box[0]), new T.Vector3(...finding.box[1]));
      }
      const union = new T.Box3();
      for (const name of selected) union.union(partObjects.get(name).box);
      if (box.isEmpty()) box.copy(union);
      if (box.isEmpty()) return;
      const sphere = box.getBoundingSphere(new T.Sphere());
      // A contact point has no size: show it with some of the smaller part around it.
      let floor = radius * 0.01;
      for (const name of selected) {
        const s = partObjects.get(name).box.getBoundingSphere(new T.Sphere());
        floor = Math.max(floor, Math.min(s.radius * 0.35, radius * 0.2));
      }
      lookAt(sphere.center, Math.max(sphere.radius, floor));
    }

    function setVisible(id, isVisible) {
      for (const o of markers.get(id) || []) o.visible = isVisible;
      requestRender();
    }

    resize();
    home();
    return { renderer, scene, camera, controls, frame, home, setVisible, render };
  }

  // ------------------------------------------------------------------------------ table

  function buildTable(data, view) {
    const tbody = document.querySelector("#findings tbody");
    const rows = [];
    const units = data.units;
    for (const f of data.findings) {
      const tr = el("tr");
      const key = f.approved !== null ? "approved" : f.status;
      tr.dataset.status = key;
      tr.dataset.id = f.id;
      tr.tabIndex = 0;
      if (f.fails) tr.classList.add("fails");
      const status = el("td");
      status.append(el("span", "badge " + f.status, f.status));
      if (f.approved !== null) status.append(" ", el("span", "badge approved", "approved"));
      if (f.fails) status.append(" ", el("span", "fails-mark", "fails"));
      if (f.surface_only) status.append(" ", el("span", "note", "surface only"));
      const parts = el("td", "part");
      parts.append(el("div", null, f.a), el("div", null, f.b));
      tr.append(
        el("td", "id", f.id),
        status,
        parts,
        el("td", "num", f.depth === null ? "\u2014" : fmt(f.depth) + " " + units),
        el("td", "num", f.volume === null ? "\u2014" : fmt(f.volume) + " " + units + "\u00b3"),
        el("td", "num", fmt(f.distance) + " " + units),
        el("td", "approved", f.approved === null ? "" : "approved: " + f.approved),
      );
      const select = () => {
        for (const r of rows) r.classList.remove("selected");
        tr.classList.add("selected");
        if (view) view.frame(f);
      };
      tr.addEventListener("click", select);
      tr.addEventListener("keydown", (e) => {
        if (e.key === "Enter" || e.key === " ") {
          e.preventDefault();
          select();
        }
      });
      rows.push(tr);
      tbody.append(tr);
    }
    if (!data.findings.some((f) => f.approved !== null)) {
      document.getElementById("findings").classList.add("no-approved");
    }
    if (!rows.length) {
      const tr = el("tr");
      const td = el("td", "empty", "No findings: every pair checked is clear.");
      td.colSpan = 7;
      tr.append(td);
      tbody.append(tr);
    }

    const filters = document.getElementById("filters");
    const counts = {};
    for (const r of rows) counts[r.dataset.status] = (counts[r.dataset.status] || 0) + 1;
    for (const key of [...STATUS_ORDER, "approved"]) {
      const label = el("label", "filter");
      const box = document.createElement("input");
      box.type = "checkbox";
      box.checked = true;
      box.dataset.status = key;
      box.addEventListener("change", () => {
        for (const r of rows) {
          if (r.dataset.status !== key) continue;
          r.hidden = !box.checked;
          if (view) view.setVisible(r.dataset.id, box.checked);
        }
      });
      label.append(box, " ", el("span", "badge " + key, key), " " + (counts[key] || 0));
      filters.append(label);
    }
  }

  // ------------------------------------------------------------------------------ start

  async function main() {
    const data = JSON.parse(document.getElementById("meshcheck-data").textContent);
    buildHeader(data);
    let view = null;
    try {
      const buffer = await decodeGeometry(document.getElementById("meshcheck-geometry").textContent);
      view = createView(data, buffer);
      document.getElementById("home").addEventListener("click", () => view.home());
    } catch (err) {
      const msg = el("p", "no-view", "The 3D view is not available in this browser: " + err.message);
      document.getElementById("view").append(msg);
    }
    buildTable(data, view);
    window.meshcheckView = view && {
      camera: view.camera,
      controls: view.controls,
      scene: view.scene,
      renderer: view.renderer,
      home: view.home,
    };
    document.body.dataset.ready = "true";
  }

  main().catch((err) => {
    document.body.dataset.ready = "error";
    throw err;
  });
})();
