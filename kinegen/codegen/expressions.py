"""Target-neutral preparation of expressions for printing."""

from __future__ import annotations

from collections.abc import Callable

import sympy as sp
from sympy.core.function import AppliedUndef, Function, UndefinedFunction
from sympy.core.mul import _keep_coeff
from sympy.printing.precedence import PRECEDENCE, precedence


def freeze_numbers(expr: sp.Expr) -> sp.Expr:
    """Replace irrational numeric subexpressions (``sqrt(2)/2``, ``cos(17/50)``, ``2*pi``) by floats.

    Integers and rationals stay exact (Python folds ``89/50`` at compile time, C ``89.0/50.0``).
    """

    def is_constant(e: sp.Basic) -> bool:
        return isinstance(e, sp.Expr) and e.is_number and not e.is_Rational and not e.is_Float

    return expr.replace(is_constant, lambda e: sp.Float(float(sp.N(e, 30))))


class PrecedenceOnce:
    """A printer mixin: SymPy's sums and products printed with each expression's precedence
    computed once and kept until :meth:`forget`, and each expression type's print method found once
    (:meth:`_print`: SymPy's ``Printer._print`` walks the type's classes at every node). SymPy's printers ask for it up to three times per
    node, a product's each time through ``could_extract_minus_sign``, which builds the product's
    negation to compare it with itself (~a third of printing the excavator's kernels). The same
    text: the precedence of an expression is a function of the expression, and :meth:`_print_Add`
    and :meth:`_print_Mul` are SymPy's (``StrPrinter``'s and ``CodePrinter``'s, SymPy pinned
    exactly) with only their precedences taken from here, and :meth:`_print` calls the method
    ``Printer._print`` finds. ``doprint`` forgets first, and so does
    :class:`kinegen.codegen.shapes.Shapes` before each group's statements: a printer kept for the
    process does not keep every expression it printed alive."""

    def __init_subclass__(cls, **kwargs: object) -> None:
        super().__init_subclass__(**kwargs)
        replaced_methods = (("_print", ("Printer",)), ("_print_Add", ("StrPrinter",)), ("_print_Mul", ("CodePrinter", "C89CodePrinter")))
        for name, owners in replaced_methods:
            replaced = next(c for c in cls.__mro__[cls.__mro__.index(PrecedenceOnce) + 1 :] if name in c.__dict__)
            if replaced.__name__ not in owners:  # a printer whose own method this mixin would hide
                raise TypeError(
                    f"{cls.__name__}: PrecedenceOnce.{name} stands for {' or '.join(owners)}'s, not {replaced.__name__}'s"
                )

    def forget(self) -> None:
        self.__dict__["_precedences"] = {}

    def doprint(self, expr: sp.Basic, assign_to: object = None) -> str:
        self.forget()
        return super().doprint(expr, assign_to)

    def _print(self, expr: object, **kwargs: object) -> str:
        # Printer._print with the method it finds for a type found once: the same method, called the same way
        kind = type(expr)
        key = (type(self), kind)
        method = _METHODS[key] if key in _METHODS else _METHODS.setdefault(key, _method(type(self), kind))
        if method is None or (kind.__dictoffset__ and self.printmethod in vars(expr)):  # (an object printing itself)
            return super()._print(expr, **kwargs)
        self._print_level += 1
        try:
            return method(self, expr, **kwargs)
        finally:
            self._print_level -= 1

    def precedence_of(self, item: sp.Basic) -> int:
        """SymPy's ``precedence(item)``, kept."""
        known = self.__dict__.setdefault("_precedences", {})
        value = known.get(item)
        if value is None:
            value = known[item] = _precedence(item)
        return value

    def parenthesize(self, item: sp.Basic, level: int, strict: bool = False) -> str:
        value = self.precedence_of(item)
        if value < level or (not strict and value <= level):
            return f"({self._print(item)})"
        return self._print(item)

    def _print_Add(self, expr: sp.Add, order: str | None = None) -> str:
        # StrPrinter._print_Add
        prec = self.precedence_of(expr)
        parts = []
        for term in self._as_ordered_terms(expr, order=order):
            text = self._print(term)
            if text.startswith("-") and not term.is_Add:
                sign, text = "-", text[1:]
            else:
                sign = "+"
            parts += [sign, f"({text})" if self.precedence_of(term) < prec or term.is_Add else text]
        sign = parts.pop(0)
        return ("" if sign == "+" else sign) + " ".join(parts)

    def _print_Mul(self, expr: sp.Mul, **kwargs: object) -> str:
        # CodePrinter._print_Mul (C89CodePrinter's first looks for a macro: SymPy's own path then)
        if expr in getattr(self, "math_macros", {}):
            return super()._print_Mul(expr, **kwargs)
        prec = self.precedence_of(expr)
        c, e = expr.as_coeff_Mul()
        if c is not sp.S.One and (c.p < 0 if c.is_Rational else c < 0):  # c < 0 (most products have none: S.One)
            expr = _keep_coeff(-c, e)
            sign = "-"
        else:
            sign = ""
        a: list[sp.Basic] = []  # the numerator's factors
        b: list[sp.Basic] = []  # the denominator's (if any)
        pow_paren = []  # powers with exponent -1 of a product of more than one factor
        args = expr.as_ordered_factors() if self.order not in ("old", "none") else sp.Mul.make_args(expr)
        for item in args:
            if item.is_commutative and item.is_Pow and item.exp.is_Rational and item.exp.is_negative:
                if item.exp != -1:
                    b.append(sp.Pow(item.base, -item.exp, evaluate=False))
                else:
                    if len(item.args[0].args) != 1 and isinstance(item.base, sp.Mul):
                        pow_paren.append(item)
                    b.append(sp.Pow(item.base, -item.exp))
            else:
                a.append(item)
        a = a or [sp.S.One]
        if len(a) == 1 and sign == "-":  # unary minus: between Mul and Pow
            a_str = [self.parenthesize(a[0], 0.5 * (PRECEDENCE["Pow"] + PRECEDENCE["Mul"]))]
        else:
            a_str = [self.parenthesize(x, prec) for x in a]
        b_str = [self.parenthesize(x, prec) for x in b]
        for item in pow_paren:
            if item.base in b:
                b_str[b.index(item.base)] = f"({b_str[b.index(item.base)]})"
        if not b:
            return sign + "*".join(a_str)
        if len(b) == 1:
            return sign + "*".join(a_str) + "/" + b_str[0]
        return sign + "*".join(a_str) + "/({})".format("*".join(b_str))


#: (printer class, expression type) -> the printer's method for it, None where SymPy's own dispatch decides
_METHODS: dict[tuple[type, type], Callable[..., str] | None] = {}


def _method(printer: type, kind: type) -> Callable[..., str] | None:
    """The ``_print_<class>`` method SymPy's ``Printer._print`` calls for an expression of type ``kind``
    (its class walk: an undefined function's own classes skipped, a renamed subclass of a known
    function too), or None where it does something else: an object that prints itself (its type
    has the printer's ``printmethod``), a class, no method (``emptyPrinter``)."""
    if issubclass(kind, type) or (printer.printmethod and hasattr(kind, printer.printmethod)):
        return None
    classes = kind.__mro__
    if AppliedUndef in classes:
        classes = classes[classes.index(AppliedUndef) :]
    if UndefinedFunction in classes:
        classes = classes[classes.index(UndefinedFunction) :]
    if Function in classes:
        i = classes.index(Function)
        classes = tuple(c for c in classes[:i] if c.__name__ == classes[0].__name__ or c.__name__.endswith("Base")) + classes[i:]
    for cls in classes:
        method = getattr(printer, "_print_" + cls.__name__, None)
        if method is not None:
            return method
    return None


def _precedence(item: sp.Basic) -> int:
    """SymPy's ``precedence(item)``. A product's without building its negation: SymPy's
    ``Mul.could_extract_minus_sign`` compares the product with its negation only to rule out
    ``zoo`` (``-zoo*x == zoo*x``), so a product without ``zoo`` that starts with a negative number
    can have a minus sign extracted, and one that does not start so cannot."""
    if type(item) is sp.Mul and sp.S.ComplexInfinity not in item.args:
        if any(
            hasattr(arg, "precedence") and isinstance(arg, Function) and arg.precedence < PRECEDENCE["Mul"] for arg in item.args
        ):
            return PRECEDENCE["Mul"]
        first = item.args[0]
        return PRECEDENCE["Add"] if first.is_Number and first.is_extended_negative else PRECEDENCE["Mul"]
    return precedence(item)
