!> Checks of a material's fracture input (docs/input.md, "&material"): which criteria are
!> on, their strength or limit strain and fracture energy, and, once the grid is known,
!> that no softening branch snaps back on the cells (refused with the largest cell allowed).
module iem_input_fracture
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use iem_kinds, only: wp
  use iem_constants, only: unset_real
  use iem_strings, only: rtoa
  use iem_config, only: config_t, material_config_t
  use iem_input_checks, only: bad
  use iem_fracture_law, only: fracture_law_t, fracture_law, largest_band, crit_shear, &
                              soft_linear, soft_bilinear
  use iem_spring_constants, only: spring_moduli
  implicit none
  private
  public :: check_fracture_keys, check_fracture_cells, check_fracture_scene, material_fracture_law

  !> Names of each criterion's strength, limit strain and energy, as the input writes them.
  character(len=*), parameter :: strength_key(3) = [character(len=26) :: 'tensile_strength', &
    'compressive_strength', 'shear_strength']
  character(len=*), parameter :: strain_key(3) = [character(len=26) :: &
    'tensile_failure_strain', 'compressive_failure_strain', 'shear_failure_strain']
  character(len=*), parameter :: energy_key(3) = [character(len=26) :: 'fracture_energy', &
    'crushing_energy', 'shear_fracture_energy']

contains

  !> The fracture keys of material mat (group label) after reading: with fracture = .true.
  !> tension needs its strength or limit strain (not both) and fracture_energy; crushing and
  !> shear are on when one of theirs is given, and then need their energy; every value
  !> given > 0 and finite. Without fracture none of the fracture keys may be given. Unset
  !> values (unset_real) become 0.
  subroutine check_fracture_keys(mat, label, stat, msg)
    type(material_config_t), intent(inout) :: mat
    character(len=*), intent(in) :: label
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    real(wp) :: v(3, 3)
    integer :: i, j
    stat = 0
    msg = ''
    ! v(:, i): strength, limit strain, energy of criterion i
    v(:, 1) = [mat%tensile_strength, mat%tensile_failure_strain, mat%fracture_energy]
    v(:, 2) = [mat%compressive_strength, mat%compressive_failure_strain, mat%crushing_energy]
    v(:, 3) = [mat%shear_strength, mat%shear_failure_strain, mat%shear_fracture_energy]
    if (.not. mat%fracture) then
      do i = 1, 3
        do j = 2, 3
          if (v(j, i) /= unset_real) then
            call bad(label, trim(key_name(j, i)), rtoa(v(j, i)), 'is used only with '// &
                     'fracture = .true.', stat, msg)
            return
          end if
        end do
      end do
      call zero_unset()
      return
    end if
    if (mat%nonlinear) then
      call bad(label, 'fracture', '.true.', 'cannot yet be combined with nonlinear = .true. '// &
               '(springs that fail soften from an elastic line; docs/model.md, '// &
               '"Fracture")', stat, msg)
      return
    end if
    do i = 1, 3
      do j = 1, 3
        if (v(j, i) == unset_real) cycle
        if (.not. ieee_is_finite(v(j, i)) .or. .not. v(j, i) > 0.0_wp) then
          call bad(label, trim(key_name(j, i)), rtoa(v(j, i)), 'must be > 0 and finite'// &
                   trim(unit(j)), stat, msg)
          return
        end if
      end do
      if (v(1, i) /= unset_real .and. v(2, i) /= unset_real) then
        call bad(label, trim(strain_key(i)), rtoa(v(2, i)), 'and '//trim(strength_key(i))// &
                 ' = '//rtoa(v(1, i))//' are both given: give one of them (the limit '// &
                 'strain is the strength over the modulus)', stat, msg)
        return
      end if
      if (v(1, i) == unset_real .and. v(2, i) == unset_real) then
        if (i == 1) then
          call bad(label, 'tensile_strength', '(not given)', 'is required with fracture = '// &
                   '.true.: the stress at which springs begin to crack [Pa] (or give '// &
                   'tensile_failure_strain, the strain at which they do)', stat, msg)
          return
        else if (v(3, i) /= unset_real) then
          call bad(label, trim(energy_key(i)), rtoa(v(3, i)), 'needs '// &
                   trim(strength_key(i))//' or '//trim(strain_key(i))//' (the '// &
                   'criterion it belongs to is on only when one of them is given)', stat, msg)
          return
        end if
      else if (v(3, i) == unset_real) then
        call bad(label, trim(energy_key(i)), '(not given)', 'is required with '// &
                 trim(key_name(merge(1, 2, v(1, i) /= unset_real), i))//' and fracture = '// &
                 '.true.: the energy a crack dissipates per unit area [J/m^2]', stat, msg)
        return
      end if
    end do
    call zero_unset()

  contains

    !> The input name of value j (strength, limit strain, energy) of criterion i.
    function key_name(j, i) result(name)
      integer, intent(in) :: j, i
      character(len=26) :: name
      select case (j)
      case (1)
        name = strength_key(i)
      case (2)
        name = strain_key(i)
      case default
        name = energy_key(i)
      end select
    end function key_name

    !> The unit of value j for messages.
    function unit(j) result(u)
      integer, intent(in) :: j
      character(len=9) :: u
      character(len=9), parameter :: units(3) = [character(len=9) :: ' [Pa]', '', ' [J/m^2]']
      u = units(j)
    end function unit

    !> Unset fracture values become 0 (not given).
    subroutine zero_unset()
      if (mat%tensile_failure_strain == unset_real) mat%tensile_failure_strain = 0.0_wp
      if (mat%compressive_failure_strain == unset_real) mat%compressive_failure_strain = 0.0_wp
      if (mat%shear_failure_strain == unset_real) mat%shear_failure_strain = 0.0_wp
      if (mat%fracture_energy == unset_real) mat%fracture_energy = 0.0_wp
      if (mat%crushing_energy == unset_real) mat%crushing_energy = 0.0_wp
      if (mat%shear_fracture_energy == unset_real) mat%shear_fracture_energy = 0.0_wp
    end subroutine zero_unset
  end subroutine check_fracture_keys

  !> The fracture law of material mat on cells lx x ly (ok = .false.: criterion bad snaps
  !> back). A material without fracture gets a law whose criteria are all off.
  subroutine material_fracture_law(mat, plane_strain, lx, ly, law, ok, bad_crit)
    type(material_config_t), intent(in) :: mat
    logical, intent(in) :: plane_strain
    real(wp), intent(in) :: lx, ly
    type(fracture_law_t), intent(out) :: law
    logical, intent(out) :: ok
    integer, intent(out) :: bad_crit
    real(wp) :: strength(3), strain(3), energy(3)
    ok = .true.
    bad_crit = 0
    if (.not. mat%fracture) return
    strength = [mat%tensile_strength, mat%compressive_strength, mat%shear_strength]
    where (strength == unset_real) strength = 0.0_wp
    strain = [mat%tensile_failure_strain, mat%compressive_failure_strain, &
              mat%shear_failure_strain]
    energy = [mat%fracture_energy, mat%crushing_energy, mat%shear_fracture_energy]
    call fracture_law(mat%young, mat%poisson, plane_strain, lx, ly, strength, strain, energy, &
                      law, ok, bad_crit, softening_shape(mat))
  end subroutine material_fracture_law

  !> Refuse fracture (a material with fracture = .true. or a shape with material = 'crack')
  !> in a body that also has nonlinear springs: the force kernel has one or the other.
  subroutine check_fracture_scene(cfg, mat_labels, shape_labels, stat, msg)
    type(config_t), intent(in) :: cfg
    character(len=*), intent(in) :: mat_labels(:), shape_labels(:)
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=*), parameter :: why = 'cannot yet be combined with nonlinear springs '// &
      '(springs that fail soften from an elastic line; docs/model.md, "Fracture"): '
    integer :: k, nl
    stat = 0
    msg = ''
    nl = findloc(cfg%materials(:)%nonlinear, .true., dim=1)
    if (nl == 0) return
    do k = 1, size(cfg%materials)
      if (.not. cfg%materials(k)%fracture) cycle
      call bad(trim(mat_labels(k)), 'fracture', '.true.', why//trim(mat_labels(nl))// &
               ' has nonlinear = .true.', stat, msg)
      return
    end do
    do k = 1, size(cfg%shapes)
      if (.not. cfg%shapes(k)%crack) cycle
      call bad(trim(shape_labels(k)), 'material', "'crack'", why//trim(mat_labels(nl))// &
               ' has nonlinear = .true.', stat, msg)
      return
    end do
  end subroutine check_fracture_scene

  !> Refuse a material whose softening branch would snap back on the cells lx x ly (a cell
  !> wider across the crack band than 2 E Gf / f^2, 1.2 E Gf / f^2 with bilinear softening,
  !> G for shear), naming the largest cell allowed and the smallest energy that would do on
  !> these cells.
  subroutine check_fracture_cells(cfg, labels, lx, ly, stat, msg)
    type(config_t), intent(in) :: cfg
    character(len=*), intent(in) :: labels(:)
    real(wp), intent(in) :: lx, ly
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    type(fracture_law_t) :: law
    logical :: ok, plane_strain
    integer :: k, i
    real(wp) :: m(3), modulus, h, gf(3), band, gmin
    character(len=:), allocatable :: rule
    stat = 0
    msg = ''
    plane_strain = cfg%geometry%plane == 'strain'
    do k = 1, size(cfg%materials)
      associate(mat => cfg%materials(k))
        call material_fracture_law(mat, plane_strain, lx, ly, law, ok, i)
        if (ok) cycle
        m = spring_moduli(mat%young, mat%poisson, plane_strain)
        if (i == crit_shear) then
          modulus = 2.0_wp*m(3)
          band = sqrt(lx*ly)
          rule = ' G Gf / f^2 with G = E/(2(1 + nu)); the band of a shear crack is '// &
                 'sqrt(lx ly)'
        else
          modulus = law%phi1*m(1)
          band = max(lx, ly)
          rule = ' E Gf / f^2'
          if (plane_strain) rule = rule//' with E/(1 - nu^2) for E in plane strain'
        end if
        ! 2 for linear softening, 1.2 for bilinear (its knee must lie beyond the onset)
        rule = trim(merge('2.0', '1.2', softening_shape(mat) == soft_linear))//rule// &
               ', '//trim(mat%softening)//' softening'
        gf = [mat%fracture_energy, mat%crushing_energy, mat%shear_fracture_energy]
        h = largest_band(modulus, law%onset(i), gf(i), softening_shape(mat))
        ! the energy whose band of these cells would just not snap back
        gmin = gf(i)*band/h
        call bad(trim(labels(k)), trim(energy_key(i)), rtoa(gf(i)), 'is too small for '// &
                 'cells of '//rtoa(lx)//' x '//rtoa(ly)//' m: the softening branch would '// &
                 'snap back; cells must be smaller than '//rtoa(h)//' m across the crack '// &
                 'band ('//rule//'): refine the grid, or give '//trim(energy_key(i))// &
                 ' > '//rtoa(gmin)//' J/m^2', stat, msg)
        return
      end associate
    end do
  end subroutine check_fracture_cells

  !> The softening shape of material mat (iem_fracture_law's soft_linear, soft_bilinear).
  pure integer function softening_shape(mat) result(shape)
    type(material_config_t), intent(in) :: mat
    shape = soft_linear
    if (mat%softening == 'bilinear') shape = soft_bilinear
  end function softening_shape
end module iem_input_fracture
