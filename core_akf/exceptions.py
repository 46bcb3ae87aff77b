"""Exceptions raised by the toolkit.

All of them derive from :class:`ValueError` so that callers who only know the
standard library can still catch bad input in one place.
"""


class AKFInputError(ValueError):
    """Invalid user input: wrong shape, NaN data, unknown id, duplicate sensor, ..."""


class ModelError(AKFInputError):
    """An invalid structural model (singular or non-symmetric mass matrix, ...)."""


class UndetectableError(AKFInputError):
    """The sensor set makes the augmented system undetectable (PBH test failed).

    Attributes
    ----------
    report : core_akf.statespace.DetectabilityReport
        Which eigenvalues fail the test and by how much.
    """

    def __init__(self, report):
        self.report = report
        super().__init__(
            "the sensor set is not detectable for the augmented state "
            "(the force/state estimate would drift or diverge):\n" + str(report)
            + "\nAdd strain or displacement sensors, use a Matérn force model or dummy displacements, or "
            "pass allow_undetectable=True to run the filter anyway."
        )
