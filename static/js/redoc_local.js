// Before Redoc's bundle loads: any image it would fetch from cdn.redoc.ly (the
// "API docs by Redocly" logo) is our icon instead, so nothing here leaves the server.
(function () {
  const local = document.currentScript.dataset.icon;
  const here = (value) => String(value).startsWith("https://cdn.redoc.ly/") ? local : value;
  const setAttribute = Element.prototype.setAttribute;
  Element.prototype.setAttribute = function (name, value) {
    return setAttribute.call(this, name, name === "src" ? here(value) : value);
  };
  const src = Object.getOwnPropertyDescriptor(HTMLImageElement.prototype, "src");
  Object.defineProperty(HTMLImageElement.prototype, "src", {
    get() { return src.get.call(this); },
    set(value) { src.set.call(this, here(value)); },
  });
})();
