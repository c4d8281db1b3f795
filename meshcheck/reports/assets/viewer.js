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
  // Colour says where the clash is: every part is a muted translucent grey, the selected
  // finding's two parts muted blue and sand, and only its clashing region is strong (the shared
  // solid red, the clearance witness magenta, the contact box blue), drawn over the parts.
  const PART_COLOR = 0x9aa0a6;
  const PART_A_COLOR = 0x6f8fb3;
  const PART_B_COLOR = 0xb3996f;
  const CLASH_COLOR = 0xe00000;
  const APPROVED_CLASH_COLOR = 0x1f9d55;
  const WITNESS_COLOR = 0xd000d0;
  const CONTACT_COLOR = 0x0050ff;
  const STATUS_ORDER = ["duplicate", "interference", "clearance", "touching"];
  const HIDDEN = new T.Matrix4().makeScale(0, 0, 0); // an instance drawn elsewhere for now

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

  // Part names are shown below the folder every part shares (named once in the header), as the
  // text report shows them; the full name is the element's title. Matching parts to findings
  // always uses the full names.
  let PREFIX = "";
  function short(name) {
    return PREFIX && name.startsWith(PREFIX) ? name.slice(PREFIX.length) : name;
  }

  // A part name that may wrap after each "/" (never inside a folder or file name).
  function nameEl(tag, className, name) {
    const node = document.createElement(tag);
    if (className) node.className = className;
    const pieces = visible(short(name)).split(/(?<=\/)/);
    pieces.forEach((piece, k) => {
      if (k) node.append(document.createElement("wbr"));
      node.append(piece);
    });
    node.title = visible(name);
    return node;
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
    if (s.failed_in_motion) items.push([s.failed_in_motion, "colliding in motion"]);
    if (data.audit) items.push([s.wrongly_disabled, "wrongly disabled in the SRDF"]);
    items.forEach(([n, label], k) => {
      if (k) counts.append(" \u00b7 ");
      counts.append(el("b", null, n), " " + label);
    });
    header.append(counts);

    const u = data.units;
    const settings = el("p", "settings");
    const pairs = [
      ["tolerance", data.settings_text.tolerance + " " + u],
      ["clearance", data.settings_text.clearance === null ? "not set" : data.settings_text.clearance + " " + u],
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

    for (const p of data.poses) {
      // the joint values each robot was checked at
      const pose = el("p", "pose", "pose ");
      pose.append(el("b", null, short(p.robot)), ": " + p.text);
      header.append(pose);
    }

    if (data.prefix) {
      const below = el("p", "prefix", "parts below ");
      below.append(el("b", null, data.prefix));
      header.append(below);
    }

    const inputs = el("details", "inputs");
    inputs.append(el("summary", null, data.inputs.length + " input" + (data.inputs.length === 1 ? "" : "s")));
    const list = el("ul");
    for (const name of data.inputs) list.append(el("li", null, name));
    inputs.append(list);
    header.append(inputs);

    if (data.sweeps.length) {
      // --sweep: link pairs not proven apart over the joint ranges, failing ones first and open
      const failing = data.sweeps.filter((r) => r.failed).length;
      const sweep = el("details", "sweeps");
      sweep.id = "sweeps";
      sweep.open = failing > 0;
      const n = data.sweeps.length;
      sweep.append(el("summary", null, n + " swept pair" + (n === 1 ? "" : "s") + " not proven apart" +
        (failing ? ", " + failing + " failing the run" : "")));
      const sl = el("ul");
      for (const r of data.sweeps) {
        const text = (r.failed ? "FAIL " : "") + r.status + (r.adjacent ? " (adjacent)" : "") + ": " +
          short(r.a) + " / " + short(r.b) + (r.pose ? " — " + r.pose : "") +
          (r.approved === null ? "" : " (approved: " + r.approved + ")");
        sl.append(el("li", r.failed ? "fail" : null, text));
      }
      sweep.append(sl);
      header.append(sweep);
    }

    if (data.audit) {
      // --audit-srdf: the audited entries not proven never, failing ones first and open
      const a = data.audit;
      const failing = a.rows.filter((r) => r.failed).length;
      const audit = el("details", "audit");
      audit.id = "audit";
      audit.open = failing > 0;
      audit.append(el("summary", null, "SRDF audit: " + a.summary));
      const al = el("ul");
      for (const r of a.rows) {
        const text = (r.failed ? "FAIL " : "") + r.status + " (" + r.reason + ") line " + r.line + ": " +
          short(r.a) + " / " + short(r.b) + (r.pose ? " — " + r.pose : "");
        al.append(el("li", r.failed ? "fail" : null, text));
      }
      audit.append(al);
      header.append(audit);
    }

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

  // three.js draws with WebGL 2 only: ask for a context before building anything, so a browser
  // without it gets a sentence, not an exception from inside the renderer.
  function hasWebGL() {
    try {
      const gl = window.WebGL2RenderingContext && document.createElement("canvas").getContext("webgl2");
      gl?.getExtension("WEBGL_lose_context")?.loseContext(); // a probe: give the context back
      return Boolean(gl);
    } catch (err) {
      return false;
    }
  }

  function materials() {
    const lit = (color, opacity) =>
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
    // Markers drawn over everything (transparent objects are drawn last, in renderOrder), so the
    // parts around them cannot hide them.
    const over = (color, opacity) => ({ color, depthTest: false, transparent: true, opacity });
    return {
      part: lit(PART_COLOR, 0.18),
      partA: lit(PART_A_COLOR, 0.35),
      partB: lit(PART_B_COLOR, 0.35),
      clash: lit(CLASH_COLOR, 1.0),
      approvedClash: lit(APPROVED_CLASH_COLOR, 0.35),
      strongApproved: lit(APPROVED_CLASH_COLOR, 1.0),
      edge: new T.LineBasicMaterial({ color: 0x30343a, transparent: true, opacity: 0.28 }),
      witness: new T.LineBasicMaterial(over(STATUS_COLORS.clearance, 0.45)),
      witnessPoints: new T.PointsMaterial({ ...over(STATUS_COLORS.clearance, 0.45), size: 5, sizeAttenuation: false }),
      strongWitness: new T.LineBasicMaterial(over(WITNESS_COLOR, 1.0)),
      strongWitnessPoints: new T.PointsMaterial({ ...over(WITNESS_COLOR, 1.0), size: 9, sizeAttenuation: false }),
      contact: new T.LineBasicMaterial(over(CONTACT_COLOR, 1.0)),
    };
  }

  function createStage(container) {
    const renderer = new T.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
    renderer.setPixelRatio(window.devicePixelRatio || 1);
    renderer.setClearColor(0xf4f5f7, 1);
    renderer.autoClear = false; // the overlay is drawn over the scene after clearing depth only
    container.append(renderer.domElement);
    const camera = new T.PerspectiveCamera(40, 1, 1, 10);
    const headlight = new T.DirectionalLight(0xffffff, 1.4);
    headlight.position.set(0.4, 0.6, 1);
    camera.add(headlight);
    const scene = new T.Scene();
    const overlay = new T.Scene(); // the selected clash region, always in view
    for (const s of [scene, overlay]) s.add(new T.HemisphereLight(0xffffff, 0x8a8f98, 1.6));
    scene.add(camera);
    return { renderer, camera, scene, overlay };
  }

  // A mesh placed this many times or more is drawn as one instanced mesh (one draw call for a
  // plant's thousand modules), without edge lines; fewer copies are drawn one by one, with them.
  const INSTANCED_FROM = 16;

  function addParts(data, geometries, mats, scene) {
    const edges = [];
    const edgesOf = (k) => (edges[k] ||= new T.EdgesGeometry(geometries[k], 35));
    const partObjects = new Map();
    const sceneBox = new T.Box3();
    const byMesh = new Map();
    for (const part of data.parts) {
      if (part.mesh === null) continue;
      if (!byMesh.has(part.mesh)) byMesh.set(part.mesh, []);
      byMesh.get(part.mesh).push(part);
    }
    for (const [k, parts] of byMesh) {
      const instances = parts.length >= INSTANCED_FROM ? new T.InstancedMesh(geometries[k], mats.part, parts.length) : null;
      parts.forEach((part, i) => {
        const m = matrixOf(part.matrix);
        const box = geometries[k].boundingBox.clone().applyMatrix4(m);
        sceneBox.union(box);
        if (instances) {
          instances.setMatrixAt(i, m);
          partObjects.set(part.name, { mesh: null, instances, index: i, matrix: m, box });
          return;
        }
        const mesh = new T.Mesh(geometries[k], mats.part);
        const lines = new T.LineSegments(edgesOf(k), mats.edge);
        for (const [o, order] of [[mesh, 1], [lines, 2]]) {
          o.matrixAutoUpdate = false;
          o.matrix.copy(m);
          o.renderOrder = order;
          scene.add(o);
        }
        partObjects.set(part.name, { mesh, box });
      });
      if (instances) {
        instances.renderOrder = 1;
        instances.computeBoundingSphere();
        scene.add(instances);
      }
    }
    if (sceneBox.isEmpty()) sceneBox.set(new T.Vector3(-1, -1, -1), new T.Vector3(1, 1, 1));
    return { partObjects, sceneBox };
  }

  // What each finding draws in the scene (its shared solid, its witness segment), and the box
  // its clashing region occupies: the solid's, the witness points', else the location's.
  function addMarkers(data, geometries, mats, scene) {
    const markers = new Map();
    for (const f of data.findings) {
      const marker = { solid: null, witness: [], region: new T.Box3() };
      if (f.solid !== null) {
        const m = matrixOf(data.meshes[f.solid].matrix);
        marker.solid = new T.Mesh(geometries[f.solid], f.approved !== null ? mats.approvedClash : mats.clash);
        marker.solid.matrixAutoUpdate = false;
        marker.solid.matrix.copy(m);
        marker.region.copy(geometries[f.solid].boundingBox).applyMatrix4(m);
      }
      if (f.line !== null) {
        const g = new T.BufferGeometry();
        g.setAttribute("position", new T.Float32BufferAttribute(f.line.flat(), 3));
        marker.witness = [new T.LineSegments(g, mats.witness), new T.Points(g, mats.witnessPoints)];
        for (const p of f.line) marker.region.expandByPoint(new T.Vector3(...p));
      }
      if (marker.region.isEmpty() && f.box) {
        marker.region.set(new T.Vector3(...f.box[0]), new T.Vector3(...f.box[1]));
      }
      for (const o of [marker.solid, ...marker.witness]) {
        if (!o) continue;
        o.renderOrder = 3;
        scene.add(o);
      }
      markers.set(f.id, marker);
    }
    return markers;
  }

  // The twelve edges of a box, as line segments.
  function boxOutline(box, material) {
    const corner = (i) => [i & 1 ? box.max.x : box.min.x, i & 2 ? box.max.y : box.min.y, i & 4 ? box.max.z : box.min.z];
    const edges = [0, 1, 2, 3, 4, 5, 6, 7, 0, 2, 1, 3, 4, 6, 5, 7, 0, 4, 1, 5, 2, 6, 3, 7];
    const g = new T.BufferGeometry();
    g.setAttribute("position", new T.Float32BufferAttribute(edges.flatMap(corner), 3));
    return new T.LineSegments(g, material);
  }

  // The label anchored at the clash: a pin at the anchor and a card beside it. Its text comes
  // from files, so it is set with textContent (through el) only.
  function createLabel(container) {
    const node = el("div", "clash-label");
    node.id = "clash-label";
    node.hidden = true;
    const card = el("div", "card");
    const leader = el("span", "leader");
    node.append(leader, el("span", "pin"), card);
    container.append(node);
    return { node, card, leader, anchor: null, radius: 0, ids: [] };
  }

  function labelText(f, units) {
    let title = f.status;
    if (f.status === "interference" && f.text.depth !== null) title += " \u00b7 " + f.text.depth + " " + units + " deep";
    if (f.status === "interference" && f.text.volume !== null) title += " \u00b7 " + f.text.volume + " " + units + "\u00b3";
    if (f.status === "clearance") title += " \u00b7 " + f.text.distance + " " + units + " apart";
    if (f.approved !== null) title += " \u00b7 approved";
    return [title, short(f.a), short(f.b)];
  }

  // The other part of each member: a part group's shared part left out; a pattern group (no
  // shared part, copies of one pair) names both parts of each member.
  function memberName(g, f) {
    if (g.part === null) return f.a + " \u00b7 " + f.b;
    return f.a === g.part ? f.b : f.a;
  }

  // The same, as shown: names below the shared folder.
  function memberText(g, f) {
    if (g.part === null) return short(f.a) + " \u00b7 " + short(f.b);
    return short(f.a === g.part ? f.b : f.a);
  }

  function groupNames(g, findings) {
    if (g.part === null) return findings.flatMap((f) => [f.a, f.b]);
    return [g.part, ...findings.map((f) => memberName(g, f))];
  }

  function groupText(g, findings) {
    if (g.part === null) {
      const title = findings.length + " " + g.status + " \u00b7 pattern group " + g.id;
      const more = findings.length > 1 ? " and " + (findings.length - 1) + " more alike" : "";
      return [title, memberText(g, findings[0]), "the same clash" + more];
    }
    const others = findings.map((f) => memberText(g, f));
    const more = others.length > 3 ? " and " + (others.length - 3) + " more" : "";
    return [findings.length + " " + g.status + " \u00b7 group " + g.id, short(g.part), "with " + others.slice(0, 3).join(", ") + more];
  }

  function createView(data, buffer) {
    const container = document.getElementById("view");
    const { renderer, camera, scene, overlay } = createStage(container);
    const mats = materials();
    const geometries = data.meshes.map((m) => buildGeometry(buffer, m));
    const { partObjects, sceneBox } = addParts(data, geometries, mats, scene);
    const markers = addMarkers(data, geometries, mats, scene);
    const label = createLabel(container);
    const sceneSphere = sceneBox.getBoundingSphere(new T.Sphere());
    const radius = Math.max(sceneSphere.radius, 1e-9);
    camera.near = radius / 2000;
    camera.far = radius * 200;
    const controls = new T.OrbitControls(camera, renderer.domElement);
    controls.enableDamping = false;
    controls.screenSpacePanning = true;
    const hidden = new Set(); // findings filtered out of the table and the view
    const state = { renderer, camera, scene, overlay, controls, container, label, radius, hidden };
    const tinted = []; // instances drawn as tinted meshes of their own while selected

    const { render, requestRender } = renderLoop(state);

    const look = (centre, r, direction) => {
      lookAt(state, centre, r, direction);
      render(); // at once: the label and the overlay change even when the camera does not
    };
    const home = () => look(sceneSphere.center, 0.8 * radius, new T.Vector3(1, -1.2, 0.9));
    const select = (findings, names, text) => {
      highlight({ mats, overlay, markers, partObjects, tinted }, findings, names);
      const region = new T.Box3();
      for (const f of findings) region.union(regionOf(markers.get(f.id), f, partObjects));
      label.anchor = null;
      if (region.isEmpty()) return render(); // nothing of it is drawn: the camera stays
      label.ids = findings.map((f) => f.id);
      label.anchor = region.getCenter(new T.Vector3());
      label.radius = region.getBoundingSphere(new T.Sphere()).radius;
      setLabel(label, text, findings[0]);
      fit(state, region, names.filter((n) => partObjects.has(n)).map((n) => partObjects.get(n).box), look);
    };
    const frame = (f) => select([f], [f.a, f.b], labelText(f, data.units));
    const frameGroup = (g, findings) => {
      return select(findings, groupNames(g, findings), groupText(g, findings));
    };
    const setVisible = (id, isVisible) => {
      const m = markers.get(id);
      for (const o of m ? [m.solid, ...m.witness] : []) if (o) o.visible = isVisible;
      for (const o of overlay.children) if (o.userData.id === id) o.visible = isVisible;
      if (isVisible) hidden.delete(id);
      else hidden.add(id);
      if (label.ids.every((i) => hidden.has(i))) label.node.hidden = true; // as the row goes
      requestRender();
    };
    resize(state);
    home();
    return { renderer, camera, scene, controls, frame, frameGroup, home, setVisible, render };
  }

  // Draw now (render) or on the next animation frame, once however often asked (requestRender).
  function renderLoop(state) {
    const render = () => drawFrame(state);
    let pending = false;
    const requestRender = () => {
      if (!pending) {
        pending = true;
        requestAnimationFrame(() => {
          pending = false;
          render();
        });
      }
    };
    state.controls.addEventListener("change", requestRender);
    window.addEventListener("resize", () => {
      resize(state);
      requestRender();
    });
    return { render, requestRender };
  }

  function regionOf(marker, f, partObjects) {
    const box = marker.region.clone();
    if (box.isEmpty()) for (const n of [f.a, f.b]) if (partObjects.has(n)) box.union(partObjects.get(n).box);
    return box;
  }

  // Parts muted, the selection's parts tinted, and only its clashing region strong: its solid
  // copied into the overlay scene (drawn after the depth is cleared, so no part hides it), its
  // witness segment in the strong colour, a contact's location box outlined.
  function highlight({ mats, overlay, markers, partObjects, tinted }, findings, names) {
    for (const { mesh } of partObjects.values()) if (mesh) mesh.material = mats.part;
    for (const t of tinted.splice(0)) {  // instances shown as tinted copies: back in their mesh
      t.copy.removeFromParent();
      t.instances.setMatrixAt(t.index, t.matrix);
      t.instances.instanceMatrix.needsUpdate = true;
    }
    names.forEach((n, k) => {
      const part = partObjects.get(n);
      if (!part) return;
      const material = k === 0 ? mats.partA : mats.partB;
      if (part.mesh) {
        part.mesh.material = material;
        return;
      }
      // An instance is tinted as a mesh of its own, and hidden (scaled to nothing) in its set.
      const copy = new T.Mesh(part.instances.geometry, material);
      copy.matrixAutoUpdate = false;
      copy.matrix.copy(part.matrix);
      copy.renderOrder = 1;
      part.instances.parent.add(copy);
      part.instances.setMatrixAt(part.index, HIDDEN);
      part.instances.instanceMatrix.needsUpdate = true;
      tinted.push({ ...part, copy });
    });
    for (const m of markers.values()) {
      if (m.witness.length) [m.witness[0].material, m.witness[1].material] = [mats.witness, mats.witnessPoints];
    }
    overlay.remove(...overlay.children.filter((o) => !o.isLight));
    for (const f of findings) {
      const m = markers.get(f.id);
      if (m.solid) {
        const solid = new T.Mesh(m.solid.geometry, f.approved !== null ? mats.strongApproved : mats.clash);
        solid.matrixAutoUpdate = false;
        solid.matrix.copy(m.solid.matrix);
        solid.userData.id = f.id;
        overlay.add(solid);
      }
      if (m.witness.length) [m.witness[0].material, m.witness[1].material] = [mats.strongWitness, mats.strongWitnessPoints];
      if (!m.solid && !m.witness.length && !m.region.isEmpty()) {
        const outline = boxOutline(m.region, mats.contact);
        outline.userData.id = f.id;
        overlay.add(outline);
      }
    }
  }

  function setLabel(label, lines, f) {
    const title = el("div", "title", lines[0]);
    title.dataset.status = f.approved !== null ? "approved" : f.status;
    label.card.replaceChildren(title, ...lines.slice(1).map((t) => el("div", "part", t)));
  }

  // Fit the clashing region: a point of contact has no size, so at least some of the smaller
  // part around it is shown.
  function fit(state, region, partBoxes, look) {
    const sphere = region.getBoundingSphere(new T.Sphere());
    let floor = state.radius * 0.01;
    if (partBoxes.length) {
      const smallest = Math.min(...partBoxes.map((b) => b.getBoundingSphere(new T.Sphere()).radius));
      floor = Math.max(floor, Math.min(smallest * 0.35, state.radius * 0.2));
    }
    look(sphere.center, 1.3 * Math.max(sphere.radius, floor)); // with a margin of context
  }

  // Look at a sphere along the current viewing direction (or the given one).
  function lookAt({ camera, controls }, centre, r, direction) {
    const dir = direction ? direction.clone() : camera.position.clone().sub(controls.target);
    if (dir.lengthSq() === 0) dir.set(1, -1.2, 0.9);
    dir.normalize();
    const fov = (camera.fov * Math.PI) / 180;
    const distance = (1.6 * r) / Math.sin(Math.min(fov, fov * camera.aspect) / 2);
    controls.target.copy(centre);
    camera.position.copy(centre).addScaledVector(dir, distance);
    camera.up.set(0, 0, 1);
    controls.update();
  }

  function resize({ renderer, camera, container }) {
    const w = Math.max(container.clientWidth, 1);
    const h = Math.max(container.clientHeight, 1);
    renderer.setSize(w, h, false);
    renderer.domElement.style.width = "100%";
    renderer.domElement.style.height = "100%";
    camera.aspect = w / h;
    camera.updateProjectionMatrix();
  }

  function drawFrame({ renderer, camera, scene, overlay, container, label, hidden }) {
    renderer.clear();
    renderer.render(scene, camera);
    if (overlay.children.some((o) => !o.isLight)) {
      renderer.clearDepth();
      overlay.add(camera); // its headlight lights the overlay too
      renderer.render(overlay, camera);
      scene.add(camera);
    }
    label.node.hidden = label.anchor === null || label.ids.every((id) => hidden.has(id));
    if (label.node.hidden) return;
    const p = label.anchor.clone().project(camera);
    const isInView = p.z < 1 && Math.abs(p.x) <= 1 && Math.abs(p.y) <= 1;
    label.node.hidden = !isInView;
    const h = container.clientHeight;
    const x = ((p.x + 1) / 2) * container.clientWidth;
    const y = ((1 - p.y) / 2) * h;
    label.node.style.transform = "translate(" + x.toFixed(1) + "px, " + y.toFixed(1) + "px)";
    // The card sits up and to the right, just outside the region's outline, on a leader line.
    const distance = Math.max(camera.position.distanceTo(label.anchor), 1e-12);
    const half = Math.tan((camera.fov * Math.PI) / 360);
    const reach = Math.min(Math.max((0.75 * label.radius * h) / (2 * distance * half), 12), h / 3);
    placeCard(label, reach, x, y, container.clientWidth, h);
  }

  // Up and to the right of the pin (or the side with more room), kept inside the view, with a
  // leader line from the pin to the card's nearest point.
  function placeCard({ card, leader }, reach, x, y, w, h) {
    const [cw, ch] = [card.offsetWidth, card.offsetHeight];
    const clamp = (v, lo, hi) => Math.max(lo, Math.min(v, hi));
    const right = x + reach + cw <= w || x < w / 2;
    const up = y - reach - ch >= 0 || y > h / 2;
    const left = clamp(x + (right ? reach : -reach - cw), 4, w - cw - 4) - x;
    const top = clamp(y + (up ? -reach - ch : reach), 4, h - ch - 4) - y;
    card.style.left = left.toFixed(1) + "px";
    card.style.top = top.toFixed(1) + "px";
    const nx = clamp(0, left, left + cw);
    const ny = clamp(0, top, top + ch);
    leader.style.width = Math.hypot(nx, ny).toFixed(1) + "px";
    leader.style.transform = "rotate(" + ((Math.atan2(ny, nx) * 180) / Math.PI).toFixed(2) + "deg)";
  }

  // ------------------------------------------------------------------------------ table

  function buildTable(data, view) {
    const tbody = document.querySelector("#findings tbody");
    const groupOf = new Map();
    for (const g of data.groups) for (const id of g.findings) groupOf.set(id, g);
    const rows = new Map(); // finding id -> row
    const mark = (ids) => {
      for (const r of rows.values()) r.classList.toggle("selected", ids.includes(r.dataset.id));
    };
    const selectFinding = (f) => {
      mark([f.id]);
      rows.get(f.id).scrollIntoView({ block: "nearest" });
      if (view) view.frame(f);
    };
    for (const f of data.findings) {
      const tr = findingRow(f, data.units, groupOf.get(f.id));
      activate(tr, () => selectFinding(f));
      rows.set(f.id, tr);
      tbody.append(tr);
    }
    if (!data.findings.some((f) => f.approved !== null)) {
      document.getElementById("findings").classList.add("no-approved");
    }
    if (!rows.size) {
      const tr = el("tr");
      const td = el("td", "empty", "No findings: every pair checked is clear.");
      td.colSpan = 7;
      tr.append(td);
      tbody.append(tr);
    }
    buildFilters([...rows.values()], view);
    const byId = new Map(data.findings.map((f) => [f.id, f]));
    buildGroups(data.groups, byId, selectFinding, (g, members) => {
      mark(g.findings);
      if (view) view.frameGroup(g, members);
    });
    return selectFinding;
  }

  // Click, Enter or Space selects.
  function activate(node, select) {
    node.tabIndex = 0;
    node.addEventListener("click", select);
    node.addEventListener("keydown", (e) => {
      if (e.key === "Enter" || e.key === " ") {
        e.preventDefault();
        select();
      }
    });
  }

  function findingRow(f, units, group) {
    const tr = el("tr");
    tr.dataset.status = f.approved !== null ? "approved" : f.status;
    tr.dataset.id = f.id;
    if (f.fails) tr.classList.add("fails");
    const status = el("td");
    status.append(el("span", "badge " + f.status, f.status));
    if (f.approved !== null) status.append(" ", el("span", "badge approved", "approved"));
    if (f.fails) status.append(" ", el("span", "fails-mark", "fails"));
    if (f.surface_only) status.append(" ", el("span", "note", "surface only"));
    if (group) status.append(" ", el("span", "note group-ref", "group " + group.id));
    const parts = el("td", "part");
    parts.append(nameEl("div", null, f.a), nameEl("div", null, f.b));
    if (f.elements) parts.append(el("div", "note", "collision elements: " + f.elements));
    tr.append(
      el("td", "id", f.id),
      status,
      parts,
      el("td", "num", f.text.depth === null ? "\u2014" : f.text.depth + " " + units),
      el("td", "num", f.text.volume === null ? "\u2014" : f.text.volume + " " + units + "\u00b3"),
      el("td", "num", f.text.distance + " " + units),
      el("td", "approved", f.approved === null ? "" : "approved: " + f.approved),
    );
    return tr;
  }

  function buildFilters(rows, view) {
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

  // Clash groups (findings of one status sharing a part, or copies of one clash): a line per
  // group, its members below; the line frames the whole group, a member frames that finding.
  function buildGroups(groups, byId, selectFinding, selectGroup) {
    const box = document.getElementById("groups");
    if (!groups.length) return;
    box.append(el("h2", null, "Clash groups"));
    for (const g of groups) {
      const members = g.findings.map((id) => byId.get(id));
      const node = el("div", "group");
      node.dataset.id = g.id;
      const head = el("div", "group-head");
      head.append(el("span", "id", g.id), " ", el("span", "badge " + g.status, g.status), " ");
      head.append(g.part === null ? el("span", "part", "pattern") : nameEl("span", "part", g.part), " " + members.length + " findings");
      activate(head, () => selectGroup(g, members));
      const list = el("ul");
      for (const f of members) {
        const item = el("li");
        item.dataset.id = f.id;
        item.append(el("span", "id", f.id), " ", el("span", "part", memberText(g, f)));
        activate(item, () => selectFinding(f));
        list.append(item);
      }
      node.append(head, list);
      box.append(node);
    }
  }

  // ------------------------------------------------------------------------------ start

  function showNoView(text) {
    const view = document.getElementById("view");
    view.classList.add("unavailable");
    view.append(el("p", "no-view", text));
  }

  async function main() {
    const data = JSON.parse(document.getElementById("meshcheck-data").textContent);
    PREFIX = data.prefix || "";
    buildHeader(data);
    let view = null;
    if (!hasWebGL()) {
      showNoView("WebGL is unavailable in this browser, so the 3D view cannot be shown. The findings are listed in the table.");
    } else {
      try {
        const buffer = await decodeGeometry(document.getElementById("meshcheck-geometry").textContent);
        view = createView(data, buffer);
        document.getElementById("home").addEventListener("click", () => view.home());
      } catch (err) {
        showNoView("The 3D view could not be started in this browser (" + err.message + "). The findings are listed in the table.");
      }
    }
    const selectFinding = buildTable(data, view);
    // Frame the worst failing finding (the table's order is most severe first).
    const worst = data.findings.find((f) => f.fails);
    if (worst) selectFinding(worst);
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
