// skisnow upload page: post a ski or grind form to the REST API (multipart), show the
// problem+json errors next to the field they name, then follow the job (GET /v1/jobs/{id},
// every second) with a progress bar until it is done or failed.
(function () {
  "use strict";
  var POLL_MS = 1000;
  var forms = document.querySelectorAll("form.upload-form");
  if (!forms.length) { return; }

  function fieldNames(form) {
    var names = [];
    Array.prototype.forEach.call(form.elements, function (el) {
      if (el.name && names.indexOf(el.name) < 0) { names.push(el.name); }
    });
    return names;
  }

  // The fields a problem+json answer is about, as [[field, reason], ...]; "form" when it names
  // none of the form's fields. The API names the field in `errors` (request validation), in
  // `field`, as the first word(s) of `detail` ("file: ...", "name 'x' must ...", "length_mm
  // must ...") or as "<a> and <b> must be given"; a taken name is 409 "... named 'x' ...";
  // camber CSV errors start with "line N:"; format errors (413, 415) and others that quote the
  // uploaded file's name are about the file.
  function problemFields(status, body, names, fileName) {
    var has = function (n) { return names.indexOf(n) >= 0; };
    var out = [];
    if (body && Array.isArray(body.errors) && body.errors.length) {
      body.errors.forEach(function (e) {
        var f = String(e.field || "").split(".").pop();
        out.push(has(f) ? [f, e.reason] : ["form", (e.field || "input") + ": " + e.reason]);
      });
      return out;
    }
    var detail = (body && (body.detail || body.title)) || ("the service answered HTTP " + status);
    if (body && body.field && has(body.field)) { return [[body.field, detail]]; }
    var named = /^([a-z_]+)(?: and ([a-z_]+))?\b/.exec(detail);
    if (!named || !has(named[1])) {
      named = /\b([a-z_]+)(?: and ([a-z_]+))? must be given\b/.exec(detail);
    }
    if (named && has(named[1])) {
      out.push([named[1], detail]);
      if (named[2] && has(named[2])) { out.push([named[2], detail]); }
      return out;
    }
    if (status === 409 && / named /.test(detail)) { return [["name", detail]]; }
    if (status === 413 || status === 415 || /^line \d+/.test(detail) ||
        (fileName && detail.indexOf(fileName) >= 0)) {
      return [["file", detail]];
    }
    return [["form", detail]];
  }
  window.skisnowUpload = { problemFields: problemFields };

  function clearErrors(form) {
    Array.prototype.forEach.call(form.querySelectorAll(".field .error"), function (el) {
      el.textContent = "";
      el.hidden = true;
    });
    Array.prototype.forEach.call(form.querySelectorAll(".field.has-error"), function (el) {
      el.classList.remove("has-error");
    });
    Array.prototype.forEach.call(form.querySelectorAll("[aria-invalid]"), function (el) {
      el.removeAttribute("aria-invalid");
    });
    var alert = form.querySelector(".alert");
    alert.textContent = "";
    alert.hidden = true;
  }

  function showErrors(form, errors) {
    var kind = form.dataset.kind, alert = form.querySelector(".alert"), first = null;
    errors.forEach(function (pair) {
      var slot = pair[0] === "form" ? null : document.getElementById(kind + "-" + pair[0] + "-error");
      if (!slot) {
        var line = document.createElement("div");
        line.textContent = pair[1];
        alert.appendChild(line);
        alert.hidden = false;
        return;
      }
      slot.textContent = (slot.textContent ? slot.textContent + "; " : "") + pair[1];
      slot.hidden = false;
      var wrap = slot.closest(".field");
      wrap.classList.add("has-error");
      var input = document.getElementById(kind + "-" + pair[0]);
      if (input) { input.setAttribute("aria-invalid", "true"); }
      var details = wrap.closest("details");
      if (details) { details.open = true; }
      first = first || input;
    });
    if (first && first.focus) { first.focus(); }
  }

  function jsonOf(resp) {
    return resp.text().then(function (text) {
      var body = null;
      try { body = JSON.parse(text); } catch (e) { body = null; }
      return { status: resp.status, body: body };
    });
  }

  function fmtUm(m) { return (m * 1e6).toPrecision(3) + " µm"; }

  function accepted(kind, body) {
    var item = body.item || {}, meta = item.metadata || {};
    if (kind === "grind" && body.iso25178) {
      var grid = meta.grid ? meta.grid.join(" × ") + " grid, " : "";
      // what was removed from the heights is said, never done silently (docs/topography.md)
      var removed = { plane: "least-squares plane removed", mean: "mean removed",
        none: "heights kept as given" }[meta.detrend];
      return "Checked: " + grid + (removed ? removed + ", " : "") + "Sa " +
        fmtUm(body.iso25178.Sa_m) + ", Sq " + fmtUm(body.iso25178.Sq_m) +
        ". Building the lookup table of grind " + item.name + ".";
    }
    if (kind === "ski" && body.data) {
      // how the file was read, and what its sampling costs (app.jobs.uploads._upload_notes)
      var notes = (body.data.notes || []).map(function (n) { return " Note: " + n + "."; });
      return "Checked: " + body.data.load_cases + " load cases, " + body.data.samples_per_case +
        " samples each." + notes.join("") + " Training the camber network of ski " +
        item.name + ".";
    }
    return "Accepted " + kind + " " + (item.name || "") + ".";
  }

  function fmtDuration(s) {
    if (s < 90) { return Math.max(1, Math.round(s)) + " s"; }
    return Math.round(s / 60) + " min";
  }

  // Follow a job until done or failed; on done, link to the form with the item selected.
  function watch(form, jobId, note) {
    var kind = form.dataset.kind, panel = document.getElementById(kind + "-job");
    var bar = panel.querySelector("progress"), percent = panel.querySelector(".percent");
    var state = panel.querySelector(".state"), message = panel.querySelector(".message");
    var queue = panel.querySelector(".queue");
    var error = panel.querySelector(".job-error"), link = panel.querySelector(".done-link");
    panel.hidden = false;
    panel.dataset.job = jobId;
    panel.querySelector(".job-id").textContent = jobId;
    panel.querySelector(".accepted").textContent = note || "";
    error.hidden = true;
    link.hidden = true;
    var oldDelete = document.getElementById(kind + "-delete-failed");
    if (oldDelete) { oldDelete.parentNode.hidden = true; }
    var oldItemLink = document.getElementById(kind + "-item-link");
    if (oldItemLink) { oldItemLink.hidden = true; }
    bar.value = 0;
    percent.textContent = "0 %";
    state.textContent = "queued";
    message.textContent = "";
    queue.textContent = "";
    var failures = 0;
    function poll() {
      if (panel.dataset.job !== jobId) { return; }  // a newer upload took the panel
      // with team tokens a job is shown only to its team: poll with the form's token
      var headers = { accept: "application/json" };
      var token = form.querySelector("[data-token]");
      if (token && token.value) { headers.authorization = "Bearer " + token.value.trim(); }
      fetch("/v1/jobs/" + encodeURIComponent(jobId), { headers: headers })
        .then(jsonOf)
        .then(function (r) {
          if (r.status !== 200 || !r.body) {
            state.textContent = "unknown";
            error.textContent = (r.body && r.body.detail) || ("job " + jobId + " not found");
            error.hidden = false;
            return;
          }
          failures = 0;
          var job = r.body;
          bar.value = job.progress;
          percent.textContent = Math.round(100 * job.progress) + " %";
          state.textContent = job.state;
          state.dataset.state = job.state;
          message.textContent = job.message ? "— " + job.message : "";
          var where = "";
          if (job.state === "queued" && job.queue_position) {
            where = " — number " + job.queue_position + " in the " + job.lane + "-job queue (" +
              job.ahead + " ahead)";
          }
          if (job.estimate_s !== null && job.estimate_s !== undefined &&
              (job.state === "queued" || job.state === "running")) {
            where += "; done in about " + fmtDuration(job.estimate_s) + " (estimate from " +
              job.estimate_basis + " finished job" + (job.estimate_basis === 1 ? "" : "s") + ")";
          }
          queue.textContent = where;
          if (job.state === "done") {
            link.href = form.dataset.return + "&" + kind + "=" + encodeURIComponent(job.item);
            link.textContent = "Compute a contact with " + kind + " " + job.item;
            link.hidden = false;
            var itemLink = document.getElementById(kind + "-item-link");
            if (itemLink) {  // a ski's page: the beam its job identified, or why there is none
              itemLink.href = "/" + kind + "s/" + encodeURIComponent(job.item);
              itemLink.textContent = "Beam, camber and misfit of " + kind + " " + job.item;
              itemLink.hidden = false;
            }
          } else if (job.state === "failed") {
            error.textContent = "The job failed: " + (job.error || "no reason given") +
              ". Nothing was kept but the reason; correct the data and upload again (the " +
              "same name replaces the failed " + kind + "), or delete it.";
            error.hidden = false;
            var del = document.getElementById(kind + "-delete-failed");
            if (del && job.item) {
              del.dataset.delete = "/v1/" + kind + "s/" + encodeURIComponent(job.item);
              del.dataset.label = kind + " " + job.item;
              del.parentNode.hidden = false;
            }
          } else {
            setTimeout(poll, POLL_MS);
          }
        }, function () {
          failures += 1;
          message.textContent = "— the service does not answer; trying again";
          setTimeout(poll, POLL_MS * Math.min(10, 1 + failures));
        });
    }
    poll();
  }

  Array.prototype.forEach.call(forms, function (form) {
    var kind = form.dataset.kind, names = fieldNames(form);
    var button = form.querySelector("button[type=submit]"), buttonText = button.textContent;
    var fileInput = form.elements.namedItem("file");
    form.addEventListener("input", function (ev) {
      var wrap = ev.target.closest && ev.target.closest(".field.has-error");
      if (!wrap) { return; }
      wrap.classList.remove("has-error");
      var slot = wrap.querySelector(".error");
      slot.hidden = true;
      slot.textContent = "";
    });
    form.addEventListener("submit", function (ev) {
      ev.preventDefault();
      clearErrors(form);
      var file = fileInput.files[0], max = Number(form.dataset.maxBytes);
      if (file && file.size > max) {
        showErrors(form, [["file", "file " + file.name + " has " + file.size +
          " bytes; the upload limit is " + max + " bytes"]]);
        return;
      }
      // empty optional fields are left out: the API's defaults apply
      var sent = new FormData();
      new FormData(form).forEach(function (value, key) {
        if (typeof value !== "string" || value.trim() !== "") { sent.append(key, value); }
      });
      var headers = { accept: "application/json" };
      var token = form.querySelector("[data-token]");
      if (token && token.value) { headers.authorization = "Bearer " + token.value.trim(); }
      button.disabled = true;
      button.textContent = "Uploading…";
      fetch(form.getAttribute("action"), { method: "POST", body: sent, headers: headers })
        .then(jsonOf)
        .then(function (r) {
          if (r.status === 202 && r.body && r.body.job) {
            history.replaceState(null, "", "?" + kind + "_job=" + encodeURIComponent(r.body.job));
            watch(form, r.body.job, accepted(kind, r.body));
          } else {
            showErrors(form, problemFields(r.status, r.body, names, file ? file.name : ""));
          }
        }, function () {
          showErrors(form, [["form", "The upload did not reach the service (network error, " +
            "or the file is over the limit); nothing was stored."]]);
        })
        .then(function () {
          button.disabled = false;
          button.textContent = buttonText;
        });
    });
    // reloading the page keeps following the job
    var resume = new URLSearchParams(window.location.search).get(kind + "_job");
    if (resume) { watch(form, resume, ""); }
  });
})();
