"""specula: spectral appearance data from Python (docs/python.md).

Stores of hyperspectral images, collections, BRDF samples and grids, bases and coefficient maps, read and written
as numpy arrays; block streaming, PCA, NMF and projection; the BRDF codec (.spc), rendering and fidelity comparison;
spectra to colour. The compiled bindings live in specula._specula; this package re-exports them with a few
pure-Python conveniences (to_xarray).

Arrays: properties of specula objects (Grid.values, Basis.components, ...) are read-only views into the object;
everything a function or method returns is an array the caller owns.
"""
from ._specula import *  # noqa: F401,F403
from ._specula import (Basis, Grid, MissingObjectError, Store, __version__)  # noqa: F401
from . import _specula

__all__ = [n for n in dir(_specula) if not n.startswith("_")]


def _missing_object_str(self):
    # A KeyError's str() quotes its key; this one is a message.
    return str(self.args[0]) if self.args else ""


MissingObjectError.__str__ = _missing_object_str


def _basis_origin(self):
    """Where the basis lives ('STORE.h5:NAME' when read from or saved in a store), or None."""
    return self.__dict__.get("_origin")


Basis.origin = property(_basis_origin)


def _xarray():
    try:
        import xarray
    except ImportError as e:
        raise ImportError("to_xarray needs xarray (Debian: apt install python3-xarray; pip install xarray)") from e
    return xarray


def _store_to_xarray(self, name, masked=float("nan")):
    """Image or collection `name` as an xarray.DataArray with a wavelength coordinate (nm): an image (y, x,
    wavelength) with masked pixels `masked` (NaN by default), a collection (spectrum, wavelength) with the
    spectra's names as coordinate. Needs xarray."""
    xr = _xarray()
    kind = self.info(name)["kind"]
    info = self.info(f"{kind}/{name}") if "/" not in name else self.info(name)
    attrs = {"units": info["units"], "store": self.path, "name": info["name"]}
    if kind == "image":
        data = self.image(info["name"], masked=masked)
        return xr.DataArray(data, dims=("y", "x", "wavelength"),
                            coords={"wavelength": ("wavelength", info["wavelengths"], {"units": "nm"})},
                            name=info["name"], attrs=attrs)
    if kind == "collection":
        return xr.DataArray(self.collection(info["name"]), dims=("spectrum", "wavelength"),
                            coords={"spectrum": self.collection_names(info["name"]),
                                    "wavelength": ("wavelength", info["wavelengths"], {"units": "nm"})},
                            name=info["name"], attrs=attrs)
    raise UsageError(f"{self.path}: to_xarray: {name} is a {kind}; images and collections convert")  # noqa: F405


def _grid_to_xarray(self):
    """The grid as an xarray.DataArray (wavelength, theta_h, theta_d, phi_d) of BRDF values in 1/sr (values times
    scale; NaN where a cell holds no data), indexed by MERL cell. Needs xarray."""
    xr = _xarray()
    import numpy as np
    v = np.where(self.values < 0, np.float32(np.nan), self.values * np.float32(self.scale))
    return xr.DataArray(v, dims=("wavelength", "theta_h", "theta_d", "phi_d"),
                        coords={"wavelength": ("wavelength", self.wavelengths, {"units": "nm"})},
                        attrs={"units": "1/sr"})


Store.to_xarray = _store_to_xarray
Grid.to_xarray = _grid_to_xarray
