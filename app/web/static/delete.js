// skisnow delete buttons (upload page, ski page): <button data-delete="/v1/skis/NAME"
// data-label="ski NAME"> asks to confirm, then sends DELETE to the REST route from this page
// (same origin: the write guard of app/api/access.py lets it through; with team tokens the
// page's team token field [data-token] is sent as a bearer token). 204: the item and its
// files are gone; any other answer shows its problem+json detail next to the button.
(function () {
  "use strict";
  function token(button) {
    var scope = button.closest("[data-token-scope]") || document;
    var field = scope.querySelector("[data-token]") || document.querySelector("[data-token]");
    return field && field.value ? field.value.trim() : "";
  }
  function say(button, text, ok) {
    var slot = button.parentNode.querySelector(".delete-result");
    if (!slot) {
      slot = document.createElement("span");
      slot.className = "delete-result";
      slot.setAttribute("role", "status");
      button.parentNode.appendChild(slot);
    }
    slot.textContent = " " + text;
    slot.className = "delete-result " + (ok ? "ok" : "error");
  }
  document.addEventListener("click", function (ev) {
    var button = ev.target.closest && ev.target.closest("button[data-delete]");
    if (!button) { return; }
    ev.preventDefault();
    var label = button.dataset.label || "this item";
    if (!window.confirm("Delete " + label + " and its files? This cannot be undone.")) { return; }
    var headers = { accept: "application/json" }, t = token(button);
    if (t) { headers.authorization = "Bearer " + t; }
    button.disabled = true;
    fetch(button.dataset.delete, { method: "DELETE", headers: headers })
      .then(function (resp) {
        if (resp.status === 204) {
          say(button, label + " deleted; its name is free.", true);
          var row = button.closest("[data-item]");
          if (row) { row.classList.add("deleted"); }
          return;
        }
        return resp.text().then(function (text) {
          var body = null;
          try { body = JSON.parse(text); } catch (e) { body = null; }
          say(button, (body && (body.detail || body.title)) ||
            ("the service answered HTTP " + resp.status), false);
          button.disabled = false;
        });
      }, function () {
        say(button, "the service did not answer; nothing was deleted", false);
        button.disabled = false;
      });
  });
})();
