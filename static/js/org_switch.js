// The organisation switch in the top bar: choosing one sends the form (no inline handler,
// which the Content-Security-Policy refuses).
document.querySelectorAll("select[data-submit-on-change]").forEach((select) => {
  select.addEventListener("change", () => select.form.submit());
});
