// skisnow technician form: load presets, porosity from snow density, busy state on submit.
(function () {
  "use strict";
  var ICE_DENSITY_KG_M3 = 917;
  var form = document.getElementById("contact-form");
  if (!form) { return; }
  var byName = function (name) { return form.elements.namedItem(name); };
  var round = function (v, digits) { var f = Math.pow(10, digits); return Math.round(v * f) / f; };

  // Load presets: a fixed load, or a fraction of the body weight, at a position [mm].
  Array.prototype.forEach.call(form.querySelectorAll("button[data-position-mm]"), function (b) {
    b.addEventListener("click", function () {
      var load = b.dataset.loadKg ? Number(b.dataset.loadKg)
        : Number(byName("body_weight_kg").value) * Number(b.dataset.bodyFraction);
      if (!isFinite(load) || load <= 0) { byName("body_weight_kg").focus(); return; }
      byName("load_kg").value = round(load, 2);
      byName("load_position_mm").value = b.dataset.positionMm;
    });
  });

  // Snow: porosity directly, or from density as n = 1 - rho / 917.
  var porosity = byName("porosity"), density = byName("snow_density_kg_m3");
  var shown = document.getElementById("porosity-from-density");
  var snowSelect = byName("snow"), modulus = byName("snow_modulus_mpa");
  function updateSnow() {
    var fromDensity = form.querySelector("input[name=snow_input][value=density]").checked;
    var named = snowSelect && snowSelect.value !== "";
    if (named) {  // a snow preset: its numbers, shown but not sent (the service fills them)
      var o = snowSelect.options[snowSelect.selectedIndex];
      modulus.value = o.dataset.modulus;
      porosity.value = o.dataset.porosity;
      density.value = o.dataset.density;
    }
    if (snowSelect) {
      document.getElementById("snow-reference").textContent =
        snowSelect.options[snowSelect.selectedIndex].dataset.hint;
    }
    modulus.disabled = named;
    porosity.disabled = named || fromDensity;
    density.disabled = named || !fromDensity;
    var rho = Number(density.value);
    shown.textContent = (density.value !== "" && isFinite(rho))
      ? "n = 1 − ρ/917 = " + round(1 - rho / ICE_DENSITY_KG_M3, 4) : "";
  }
  Array.prototype.forEach.call(form.querySelectorAll("input[name=snow_input]"), function (r) {
    r.addEventListener("change", updateSnow);
  });
  density.addEventListener("input", updateSnow);
  if (snowSelect) snowSelect.addEventListener("change", updateSnow);
  updateSnow();

  var button = document.getElementById("submit"), buttonText = button.textContent;
  form.addEventListener("submit", function () {
    button.disabled = true;
    button.textContent = "Computing…";
  });
  // coming back with the browser's back button: the page may come from the back-forward cache
  window.addEventListener("pageshow", function () {
    button.disabled = false;
    button.textContent = buttonText;
    updateSnow();
  });
})();
