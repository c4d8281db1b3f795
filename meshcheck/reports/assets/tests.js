// meshcheck HTML report of a run of clash tests: the tests in the header (each with its verdict,
// sides and settings), each finding's test named in its row, and a filter by test beside the
// status filters that hides the other tests' rows, clash groups and markers in the 3D view.
// Inlined after viewer.js only in such a report; it works on the page viewer.js built (once
// document.body.dataset.ready is set) and on the same data. Everything in the data came from the
// user's files: it is only ever put into the page with textContent.
(function () {
  "use strict";
  const UNPRINTABLE = /[\u0000-\u001f\u007f-\u009f\u200b-\u200f\u2028\u2029\u202a-\u202e\u2060-\u206f\ufeff]/g;
  function visible(value) {
    return String(value).replace(UNPRINTABLE, (c) => "\\u" + c.charCodeAt(0).toString(16).padStart(4, "0"));
  }

  function el(tag, className, text) {
    const node = document.createElement(tag);
    if (className) node.className = className;
    if (text !== undefined && text !== null) node.textContent = visible(text);
    return node;
  }

  // The objects viewer.js added to the scene for each finding, in its order: the shared solid
  // (when the finding has one), then the clearance witness's segment and points (when it has a
  // line); every one of them, and only they, drawn with renderOrder 3.
  function markerObjects(data) {
    const view = window.meshcheckView;
    const byId = new Map();
    if (!view) return byId;
    const drawn = view.scene.children.filter((o) => o.renderOrder === 3);
    let k = 0;
    for (const f of data.findings) {
      const count = (f.solid !== null ? 1 : 0) + (f.line !== null ? 2 : 0);
      byId.set(f.id, drawn.slice(k, k + count));
      k += count;
    }
    return k === drawn.length ? byId : new Map(); // not as expected: leave the view alone
  }

  function start() {
    const data = JSON.parse(document.getElementById("meshcheck-data").textContent);
    const testOf = new Map(data.findings.map((f) => [f.id, f.test]));
    const rows = [...document.querySelectorAll("#findings tbody tr[data-id]")];
    for (const tr of rows) {
      tr.dataset.test = testOf.get(tr.dataset.id);
      tr.children[1].append(" ", el("span", "note test-ref", "test " + tr.dataset.test));
    }
    const groupTest = new Map(data.groups.map((g) => [g.id, g.test]));
    const groups = [...document.querySelectorAll("#groups .group[data-id]")];

    const list = el("ul", "tests");
    list.id = "tests";
    for (const t of data.tests) {
      const item = el("li", null);
      item.dataset.test = t.name;
      item.append(
        el("span", "verdict " + (t.passed ? "pass" : "fail"), t.passed ? "PASS" : "FAIL"),
        " ",
        el("b", null, t.name),
        " ",
        el("span", "note", t.settings + " \u00b7 " + t.findings + " finding" + (t.findings === 1 ? "" : "s")),
      );
      list.append(item);
    }
    document.getElementById("header").append(list);

    const label = el("label", "filter test-filter", "test ");
    const select = document.createElement("select");
    select.id = "test-filter";
    const all = el("option", null, "all " + data.tests.length + " tests");
    all.value = "";
    select.append(all);
    for (const t of data.tests) {
      const option = el("option", null, t.name + (t.passed ? "" : " (fails)"));
      option.value = t.name;
      select.append(option);
    }
    label.append(select);
    const filters = document.getElementById("filters");
    filters.append(label);

    const markers = markerObjects(data);
    // A row shows when its status's box is checked and its test is the one chosen (or all).
    const apply = () => {
      const chosen = select.value;
      const statusShown = new Map(
        [...filters.querySelectorAll("input[data-status]")].map((box) => [box.dataset.status, box.checked]),
      );
      for (const tr of rows) {
        const isShown = (!chosen || tr.dataset.test === chosen) && statusShown.get(tr.dataset.status) !== false;
        tr.hidden = !isShown;
        for (const o of markers.get(tr.dataset.id) || []) o.visible = isShown;
      }
      for (const g of groups) g.hidden = Boolean(chosen) && groupTest.get(g.dataset.id) !== chosen;
      for (const item of list.children) item.classList.toggle("chosen", item.dataset.test === chosen);
      if (window.meshcheckView) window.meshcheckView.controls.dispatchEvent({ type: "change" }); // redraw
    };
    select.addEventListener("change", apply);
    // The status boxes (viewer.js) show and hide their rows first; then the test filter applies.
    filters.addEventListener("change", (e) => {
      if (e.target !== select) apply();
    });
    document.body.dataset.tests = "ready";
  }

  if (document.body.dataset.ready) start();
  else {
    new MutationObserver((_, observer) => {
      if (!document.body.dataset.ready) return;
      observer.disconnect();
      if (document.body.dataset.ready === "true") start();
    }).observe(document.body, { attributes: true, attributeFilter: ["data-ready"] });
  }
})();
